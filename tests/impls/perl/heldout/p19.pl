# defect box p19 (see the CATALOGUE.json of its half)
use strict;
use warnings;
+{
    base      => 'legal-q',
    catalogue => {
        class     => 'a',
        clauses   => ['B5', 'R1'],
        mechanism => 'The tolerance request (25) is checked for its block count and block length but not its block type: a 25 with block type 00, 01 or 03 and L = 5 is answered 0000.',
        keywords  => ['block type', 'tolerance'],
        trigger   => 'FE FE 00 01 01 25 01 01 00 05 00 00 01 3F000000 00 00 (a tolerance with block type 01): the box answers FE FE 00 01 10 25 00 00 00 00 00 00 00 00; it should answer 1002 (FE FE 00 01 10 25 00 00 00 00 10 02 00 00).',
        fix       => 'Refuse a 25 whose block type is not 02 with 1002, as for the count and length.',
        looks_like => 'a box that does not check the block type of any action (poses with a wrong type are refused here)',
    },
    hooks => {
        shape_ok => sub {
            my ($act, $bt, $n, $l) = @_;
            return ($n >= 1 && $l == 5) if $act == 0x25;
            return main::base_shape_ok(@_);
        },
    },
    check => sub {
        my ($t) = @_;
        my $a1 = $t->req(main::frame(act => 0x25, bt => 1, n => 1, l => 5, data => main::tol_data(1, 1)));
        my $a2 = $t->req(main::frame(act => 0x23, bt => 2, n => 1, l => 25, data => main::pose_data(1, 1)));
        return (0, "tolerance type 01 [$a1]") unless $a1 eq main::ans(0x25, 0);
        return (0, "pose type 02 [$a2]") unless $a2 eq main::ans(0x23, 0x1001);
        return (1, 'tolerance with block type 01 answered 0000');
    },
};
