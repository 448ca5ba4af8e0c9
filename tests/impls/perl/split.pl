#!/usr/bin/perl
# The seeded split of the defect boxes into tuning/ and heldout/.
#
#   perl tests/impls/perl/split.pl [--seed 20261128]
#
# Reads every defect box (defects/, tuning/ or heldout/ NAME.pl), groups them by
# class, and for each class in order a..j draws one coin with Perl's srand/rand
# (drand48, the same on every platform): 0 puts the pair's first name (sorted)
# in tuning/ and the second in heldout/, 1 the other way round.  Moves the files
# there and writes tuning/CATALOGUE.json, heldout/CATALOGUE.json and
# legal/CATALOGUE.json.  Running it again with the same seed changes nothing.
use strict;
use warnings;
use File::Basename qw(dirname);
use File::Spec;
use File::Path qw(make_path);
use Getopt::Long;
use JSON::PP;

my $seed = 20261128;
GetOptions('seed=i' => \$seed) or die "usage: split.pl [--seed N]\n";
our $DIR = File::Spec->rel2abs(dirname(__FILE__));
require "$DIR/box.pl";
our %LEGAL;

my (%where, %def);
for my $d (qw(defects tuning heldout)) {
    opendir(my $dh, "$DIR/$d") or next;
    for my $f (sort readdir $dh) {
        next unless $f =~ /^(p\d+)\.pl$/;
        my $name = $1;
        my $x = do "$DIR/$d/$f";
        die "cannot load $d/$f: " . ($@ || $!) . "\n" unless ref $x eq 'HASH';
        $where{$name} = $d;
        $def{$name}   = $x;
    }
}
my %byclass;
push @{ $byclass{ $def{$_}{catalogue}{class} } }, $_ for sort keys %def;

srand($seed);
my (%half, %cat);
for my $class (sort keys %byclass) {
    my @pair = sort @{ $byclass{$class} };
    die "class $class has " . scalar(@pair) . " boxes, not 2\n" unless @pair == 2;
    my $coin = int(rand(2));
    my ($tune, $held) = $coin ? @pair[1, 0] : @pair[0, 1];
    $half{$tune} = 'tuning';
    $half{$held} = 'heldout';
}
for my $name (sort keys %def) {
    my $h = $half{$name};
    make_path("$DIR/$h");
    if ($where{$name} ne $h) {
        rename("$DIR/$where{$name}/$name.pl", "$DIR/$h/$name.pl") or die "move $name: $!\n";
    }
    my $c = $def{$name}{catalogue};
    push @{ $cat{$h} }, {
        name       => $name,
        class      => $c->{class},
        clauses    => $c->{clauses},
        mechanism  => $c->{mechanism},
        keywords   => $c->{keywords},
        trigger    => $c->{trigger},
        fix        => $c->{fix},
        base       => $def{$name}{base},
        looks_like => $c->{looks_like},
    };
}
rmdir "$DIR/defects";
my $json = JSON::PP->new->utf8->pretty->canonical;
for my $h (qw(tuning heldout)) {
    open(my $o, '>', "$DIR/$h/CATALOGUE.json") or die;
    print $o $json->encode([ sort { $a->{name} cmp $b->{name} } @{ $cat{$h} || [] } ]);
    close $o;
}
make_path("$DIR/legal");
my @legal;
for my $name (sort keys %LEGAL) {
    my %ch = %{ $LEGAL{$name} };
    my $args = delete $ch{args};
    $ch{$_} = sprintf('%04X', $ch{$_}) for grep { /^(refusal_code|cycle_on_twice|cycle_off_idle)$/ } keys %ch;
    $ch{extension} = $ch{extension} ? 'present' : 'absent';
    push @legal, { name => $name, args => $args, choices => \%ch };
}
open(my $o, '>', "$DIR/legal/CATALOGUE.json") or die;
print $o $json->encode(\@legal);
close $o;
printf "seed %d: tuning %s; heldout %s\n", $seed,
    join(' ', sort grep { $half{$_} eq 'tuning' } keys %half),
    join(' ', sort grep { $half{$_} eq 'heldout' } keys %half);
