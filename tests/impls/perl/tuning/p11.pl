# defect box p11 (see the CATALOGUE.json of its half)
use strict;
use warnings;
my $result = 0;
+{
    base      => 'legal-p',
    catalogue => {
        class     => 'j',
        clauses   => ['E3'],
        mechanism => 'It answers the result request (27) from a result variable that is set only when a cycle ends (CycleOff after CycleOn): until the first cycle since start has ended it sends ResultCode 0, a value the box must never send.',
        keywords  => ['ResultCode', 'cycle'],
        trigger   => 'FE FE 00 01 01 27 00 00 00 00 00 00 00 00 on a fresh box: the box answers FE FE 00 01 10 27 03 01 00 05 00 00 00 00 00 00 00 00 00 (ResultCode 0); it should answer a ResultCode from E3 (1, 2, 10, 20, 202, 400 or 409), e.g. 202 while no result exists. After CycleOn, CycleOff it answers 1.',
        fix       => 'Initialise the result to a legal ResultCode (202 busy or 409) and never send 0.',
        looks_like => 'a ResultCode block decoded wrongly (the int32 in the wrong place), or a result that depends on the order of the session',
    },
    hooks => {
        action => sub {
            my ($c, $h, $data, $default) = @_;
            if ($h->{act} == 0x27) {
                main::answer($c, 0x27, 0x0000, 3, 1, 5, pack('C l>', 0, $result));
                return;
            }
            $result = 1 if $h->{act} == 0x02 && ${ main::cycle_ref($c) };
            $default->();
        },
    },
    check => sub {
        my ($t) = @_;
        my $c = $t->conn;
        my $r0 = $t->ask($c, main::plain(0x27));
        $t->ask($c, main::plain(0x01));
        $t->ask($c, main::plain(0x02));
        my $r1 = $t->ask($c, main::plain(0x27));
        return (0, "before a cycle [$r0]") unless $r0 eq main::ans(0x27, 0, pack('C l>', 0, 0));
        return (0, "after a cycle [$r1]") unless $r1 eq main::ans(0x27, 0, pack('C l>', 0, 1));
        return (1, 'ResultCode 0 before the first cycle, 1 after');
    },
};
