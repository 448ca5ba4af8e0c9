# defect box p06 (see the CATALOGUE.json of its half)
use strict;
use warnings;
+{
    base      => 'legal-p',
    catalogue => {
        class     => 'd',
        clauses   => ['B5', 'A3'],
        mechanism => 'Its receive buffer holds 4096 bytes: a frame longer than that (a pose request with 164 or more blocks) is counted away unread and refused with its action\'s error (1001), though the frame allows up to 255 blocks.',
        keywords  => ['4096', 'bytes'],
        trigger   => 'a pose request with 164 blocks, FE FE 00 01 01 23 01 A4 00 19 00 00 + 164 valid pose blocks (indexes 00..A3) + 00 00: the box answers FE FE 00 01 10 23 00 00 00 00 10 01 00 00; it should answer 0000 (163 blocks are answered 0000).',
        fix       => 'Size the receive buffer for the largest legal frame (12 + 255*25 + 2 = 6389 bytes) or parse blocks as they stream in.',
        looks_like => 'a fixed-size table of poses (a limit on the block count rather than on the frame\'s size in bytes)',
    },
    hooks => {
        pre_frame => sub {
            my ($c, $h, $total) = @_;
            return 0 if $total <= 4096;
            main::malformed($c, $h->{act}) if $h->{tt} == 1 && main::known_action($h->{act});
            $c->{skip} = $total;
            return 1;
        },
    },
    check => sub {
        my ($t) = @_;
        my $a163 = $t->req(main::pose(0, 163));
        my $a164 = $t->req(main::pose(0, 164));
        my $t255 = $t->req(main::tol(0, 255));
        return (0, "163 blocks [$a163]") unless $a163 eq main::ans(0x23, 0);
        return (0, "164 blocks [$a164]") unless $a164 eq main::ans(0x23, 0x1001);
        return (0, "255 tolerances [$t255]") unless $t255 eq main::ans(0x25, 0);
        return (1, '163 poses 0000, 164 poses 1001, 255 tolerances 0000');
    },
};
