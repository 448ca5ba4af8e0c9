# defect box p02 (see the CATALOGUE.json of its half)
use strict;
use warnings;
+{
    base      => 'legal-p',
    catalogue => {
        class     => 'e',
        clauses   => ['R3'],
        mechanism => 'Its start-word scan keeps nothing when the buffer holds no complete FE FE: a frame whose first segment is the single byte FE loses that byte, and the rest (FE 00 01 ...) is then skipped as garbage, so a frame split right after its first byte is never answered.',
        keywords  => ['split', 'FE'],
        trigger   => 'FE | FE 00 01 01 00 00 00 00 00 00 00 00 00 (the first byte in its own segment, the rest 100 ms later): the box stays silent; it should answer FE FE 00 01 10 00 00 00 00 00 00 00 00 00 as it does when the split falls anywhere else.',
        fix       => 'When no FE FE is found, keep a trailing FE (a possible first half of the start word) and wait for more bytes.',
        looks_like => 'a box that needs the 12-byte header in one read (a frame split one byte per segment is lost either way)',
    },
    hooks => { drop_partial_start => 1 },
    check => sub {
        my ($t) = @_;
        my $p = main::plain(0x00);
        my $c = $t->conn;
        $t->put($c, substr($p, 0, 1));
        Time::HiRes::sleep(0.1);
        $t->put($c, substr($p, 1));
        my $a1 = $t->frame_in($c, 0.5);
        close $c->{s};
        $c = $t->conn;
        $t->put($c, substr($p, 0, 5));
        Time::HiRes::sleep(0.1);
        $t->put($c, substr($p, 5));
        my $a5 = $t->frame_in($c, 0.5);
        close $c->{s};
        return (0, "split after 1: [$a1]") unless $a1 eq 'silent';
        return (0, "split after 5: [$a5]") unless $a5 eq main::ans(0x00, 0);
        return (1, 'split after byte 1 lost, after byte 5 answered');
    },
};
