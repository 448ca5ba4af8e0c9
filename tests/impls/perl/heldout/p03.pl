# defect box p03 (see the CATALOGUE.json of its half)
use strict;
use warnings;
my $stored = 0;
+{
    base      => 'legal-p',
    catalogue => {
        class     => 'j',
        clauses   => ['E2'],
        mechanism => 'ProgIdx (26) is answered from the stored program index before the new one is stored: the first ProgIdx after start is answered with 0, every later one with the index of the previous ProgIdx.',
        keywords  => ['ProgIdx', 'previous'],
        trigger   => 'FE FE 00 01 01 26 03 01 00 05 00 00 00 00 00 00 03 00 00 (the first ProgIdx, 3): the box answers FE FE 00 01 10 26 03 01 00 05 00 00 00 00 00 00 00 00 00 (index 0); it should answer the index 3 (... 00 00 00 00 03 00 00). A second ProgIdx 5 is answered 3.',
        fix       => 'Store the request\'s program index first and answer with it (the index of this request).',
        looks_like => 'an int32 read wrongly (the echoed value is wrong), until the same index is sent twice',
    },
    hooks => {
        action => sub {
            my ($c, $h, $data, $default) = @_;
            return $default->() unless $h->{act} == 0x26;
            main::answer($c, 0x26, 0x0000, 3, 1, 5, pack('C l>', ord($data), $stored));
            $stored = unpack('l>', substr($data, 1, 4));
        },
    },
    check => sub {
        my ($t) = @_;
        my $pi = sub { main::frame(act => 0x26, bt => 3, n => 1, l => 5, data => pack('C l>', 0, $_[0])) };
        my $c = $t->conn;
        my @got = map { $t->ask($c, $pi->($_)) } (3, 5, 5);
        my @want = map { main::ans(0x26, 0, pack('C l>', 0, $_)) } (0, 3, 5);
        for (0 .. 2) { return (0, "ProgIdx #$_ [$got[$_]]") unless $got[$_] eq $want[$_] }
        return (1, 'ProgIdx 3,5,5 answered 0,3,5');
    },
};
