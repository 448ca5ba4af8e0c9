# defect box p01 (see the CATALOGUE.json of its half)
use strict;
use warnings;
+{
    base      => 'legal-p',
    catalogue => {
        class     => 'c',
        clauses   => ['F5', 'A2'],
        mechanism => 'The TCP answer buffer is sized 12 + N*L + 3 and sent whole: every TCP answer carries one extra 00 byte after its check field, so the next answer seems to start with a stray byte.',
        keywords  => ['answer', 'extra byte'],
        trigger   => 'FE FE 00 01 01 00 00 00 00 00 00 00 00 00 (twice on one connection): the box sends FE FE 00 01 10 00 00 00 00 00 00 00 00 00 00 (15 bytes) each time; it should send the 14-byte answer FE FE 00 01 10 00 00 00 00 00 00 00 00 00.',
        fix       => 'Size and send the answer as exactly 12 + N*L + 2 bytes.',
        looks_like => 'garbage written before an answer (the stray byte is only seen when the next answer is read)',
    },
    hooks => { tcp_out => sub { $_[0] . "\x00" } },
    check => sub {
        my ($t) = @_;
        my $c = $t->conn;
        my $a1 = $t->ask($c, main::plain(0x00));
        my $a2 = $t->ask($c, main::plain(0x00));
        my $want = main::ans(0x00, 0);
        return (0, "first [$a1]") unless $a1 eq $want;
        return (0, "second [$a2]") unless $a2 eq "? 00 | $want";
        return (1, 'stray 00 after each answer');
    },
};
