# defect box p07 (see the CATALOGUE.json of its half)
use strict;
use warnings;
+{
    base      => 'legal-q',
    catalogue => {
        class     => 'c',
        clauses   => ['F3', 'A2'],
        mechanism => 'Its error answers (any non-zero error code: 1001, 1002, 0001, 0002, FFFF) are built from a copy of the request\'s header and keep the transfer type 01 instead of 10; answers with 0000 are right.',
        keywords  => ['transfer type', 'error'],
        trigger   => 'a pose whose only block has index 00 (this box starts at 01): FE FE 00 01 01 23 01 01 00 19 00 00 00 44480000 C1480000 43AF2000 43340000 00000000 42B40000 00 00: the box answers FE FE 00 01 01 23 00 00 00 00 10 01 00 00; it should answer FE FE 00 01 10 23 00 00 00 00 10 01 00 00.',
        fix       => 'Write the transfer type 10 in every answer, the error answers included.',
        looks_like => 'a box that echoes a request back instead of answering it',
    },
    hooks => {
        build_answer => sub {
            my $a = main::base_answer(@_);
            substr($a, 4, 1) = "\x01" if $_[1] != 0;
            return $a;
        },
    },
    check => sub {
        my ($t) = @_;
        my $bad = $t->req(main::pose(0, 1));
        my $good = $t->req(main::pose(1, 1));
        return (0, "bad pose [$bad]") unless $bad eq 'FE FE 00 01 01 23 00 00 00 00 10 01 00 00';
        return (0, "good pose [$good]") unless $good eq main::ans(0x23, 0);
        return (1, '1001 answered with transfer type 01');
    },
};
