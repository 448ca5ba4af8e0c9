# defect box p04 (see the CATALOGUE.json of its half)
use strict;
use warnings;
my $poses = 0;
+{
    base      => 'legal-p',
    catalogue => {
        class     => 'g',
        clauses   => ['T1', 'S4'],
        mechanism => 'On CycleOff it writes out the cycle\'s trajectory synchronously on the box\'s only thread, 20 ms per pose received while the cycle was on: CycleOff is answered late (past time_out after about 250 poses, 5 s of a 50 Hz stream) and every other connection stalls meanwhile.',
        keywords  => ['CycleOff', 'pose'],
        trigger   => 'CycleOn, one pose request with 100 blocks, then FE FE 00 01 01 02 00 00 00 00 00 00 00 00 (CycleOff): the box answers 0000 only after about 2 s (and a ping on another connection waits as long); it should answer at once. With 250 poses in the cycle the answer comes after time_out.',
        fix       => 'Answer CycleOff at once and write the trajectory out in the background (or incrementally), never blocking the event loop.',
        looks_like => 'a box that stalls as a whole from time to time, or a CycleOff that is slow regardless of the poses',
    },
    hooks => {
        action => sub {
            my ($c, $h, $data, $default) = @_;
            my $on = ${ main::cycle_ref($c) };
            if (($h->{act} == 0x23 || $h->{act} == 0x24) && $on) { $poses += $h->{n} }
            if ($h->{act} == 0x02 && $on) {
                select(undef, undef, undef, $poses * 0.020);
                $poses = 0;
            }
            $default->();
        },
    },
    check => sub {
        my ($t) = @_;
        my $c = $t->conn;
        my $other = $t->conn;
        my $quick0 = $t->ask($c, main::plain(0x02), 0.5);    # CycleOff idle: fast
        return (0, "CycleOn [...]") unless $t->ask($c, main::plain(0x01)) eq main::ans(0x01, 0);
        return (0, 'pose x255') unless $t->ask($c, main::pose(0, 100)) eq main::ans(0x23, 0);
        my $t0 = Time::HiRes::time();
        $t->put($c, main::plain(0x02));
        Time::HiRes::sleep(0.2);
        my $ping = $t->ask($other, main::plain(0x00), 5);
        my $tp = Time::HiRes::time() - $t0;
        my $off = $t->frame_in($c, 5);
        my $dt = Time::HiRes::time() - $t0;
        return (0, "CycleOff [$off]") unless $off eq main::ans(0x02, 0);
        return (0, sprintf('CycleOff after %.2fs', $dt)) unless $dt > 1.5;
        return (0, sprintf('ping after %.2fs', $tp)) unless $tp > 1.5 && $ping eq main::ans(0x00, 0);
        return (1, sprintf('CycleOff after %.1fs, ping on another connection after %.1fs', $dt, $tp));
    },
};
