# defect box p08 (see the CATALOGUE.json of its half)
use strict;
use warnings;
+{
    base      => 'legal-p',
    catalogue => {
        class     => 'b',
        clauses   => ['E1', 'E2'],
        mechanism => 'It reads the ProgIdx int32 from its low two bytes only, unsigned: program indexes 0 to 65535 are echoed right, 70000 is echoed as 4464 and -1 as 65535.',
        keywords  => ['ProgIdx', 'low'],
        trigger   => 'ProgIdx 70000: FE FE 00 01 01 26 03 01 00 05 00 00 00 00 01 11 70 00 00: the box answers ... 26 03 01 00 05 00 00 00 00 00 11 70 00 00 (4464); it should echo 00 01 11 70 (70000).',
        fix       => 'Decode the block value as a signed big-endian int32 (all four bytes).',
        looks_like => 'a ProgIdx answered with a stale or wrong index, or an int32 read little-endian (small indexes pass)',
    },
    hooks => { progidx_value => sub { unpack('n', substr($_[0], 2, 2)) } },
    check => sub {
        my ($t) = @_;
        my $pi = sub { main::frame(act => 0x26, bt => 3, n => 1, l => 5, data => pack('C l>', 0, $_[0])) };
        my $c = $t->conn;
        my $a3 = $t->ask($c, $pi->(3));
        my $a7 = $t->ask($c, $pi->(70000));
        return (0, "ProgIdx 3 [$a3]") unless $a3 eq main::ans(0x26, 0, pack('C l>', 0, 3));
        return (0, "ProgIdx 70000 [$a7]") unless $a7 eq main::ans(0x26, 0, pack('C l>', 0, 4464));
        return (1, 'ProgIdx 70000 echoed as 4464');
    },
};
