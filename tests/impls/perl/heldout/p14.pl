# defect box p14 (see the CATALOGUE.json of its half)
use strict;
use warnings;
my $stored = 0;
+{
    base      => 'legal-p',
    catalogue => {
        class     => 'd',
        clauses   => ['S3', 'S6'],
        mechanism => 'It keeps every received pose in a box-wide trajectory buffer of 500 poses that only CycleOff empties: once 500 poses (blocks) have arrived since start or the last CycleOff, every pose request that does not fit is refused with 1001.',
        keywords  => ['500', 'CycleOff'],
        trigger   => 'after two pose requests of 255 and 245 blocks (500 poses), a pose with one block, FE FE 00 01 01 23 01 01 00 19 00 00 00 44480000 C1480000 43AF2000 43340000 00000000 42B40000 00 00: the box answers FE FE 00 01 10 23 00 00 00 00 10 01 00 00; it should answer 0000. After a CycleOff the same request is answered 0000 again.',
        fix       => 'Do not bound the poses accepted by a buffer (use a ring buffer, or drop the oldest), and never refuse a valid pose.',
        looks_like => 'a per-connection request budget, or poses refused depending on the cycle state',
    },
    hooks => {
        action => sub {
            my ($c, $h, $data, $default) = @_;
            if ($h->{act} == 0x23 || $h->{act} == 0x24) {
                if ($stored + $h->{n} > 500) { main::answer($c, $h->{act}, 0x1001); return }
                $stored += $h->{n};
            }
            $stored = 0 if $h->{act} == 0x02;
            $default->();
        },
    },
    check => sub {
        my ($t) = @_;
        my $c = $t->conn;
        my $ok = main::ans(0x23, 0);
        my $a1 = $t->ask($c, main::pose(0, 255));
        my $a2 = $t->ask($c, main::pose(0, 245));
        return (0, "first 500 [$a1] [$a2]") unless $a1 eq $ok && $a2 eq $ok;
        my $other = $t->conn;
        my $a3 = $t->ask($other, main::pose(0, 1));
        $t->ask($c, main::plain(0x02));
        my $a4 = $t->ask($other, main::pose(0, 255));
        return (0, "501st [$a3]") unless $a3 eq main::ans(0x23, 0x1001);
        return (0, "after CycleOff [$a4]") unless $a4 eq $ok;
        return (1, 'the 501st pose refused 1001, CycleOff empties the buffer');
    },
};
