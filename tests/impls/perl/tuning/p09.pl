# defect box p09 (see the CATALOGUE.json of its half)
use strict;
use warnings;
+{
    base      => 'legal-q',
    catalogue => {
        class     => 'e',
        clauses   => ['R3', 'F5'],
        mechanism => 'It takes a frame as complete once its header and blocks are in, without waiting for the 2-byte check field: when the check field arrives in a later segment its bytes are taken for the start of the next frame (garbage), and the connection is closed.',
        keywords  => ['check field', 'split'],
        trigger   => 'FE FE 00 01 01 00 00 00 00 00 00 00 | 00 00 (the check field in a second segment 100 ms later), then a ping: the box answers the first ping (before its check field has arrived) and then closes the connection, so the second ping is never answered; it should wait for the whole frame and answer both.',
        fix       => 'Wait for all 12 + N*L + 2 bytes and consume the check field with its frame.',
        looks_like => 'a box that closes the connection after answering (at a random time), or one that mishandles segments',
    },
    hooks => { need_bytes => sub { $_[0] - 2 } },
    check => sub {
        my ($t) = @_;
        my $p = main::plain(0x00);
        my $c = $t->conn;
        my $w1 = $t->ask($c, $p);
        my $w2 = $t->ask($c, $p);
        close $c->{s};
        return (0, "whole frames [$w1] [$w2]") unless $w1 eq main::ans(0x00, 0) && $w2 eq $w1;
        $c = $t->conn;
        $t->put($c, substr($p, 0, 12));
        my $s1 = $t->frame_in($c, 0.5);
        $t->put($c, substr($p, 12));
        Time::HiRes::sleep(0.1);
        my $s2 = $t->ask($c, $p, 0.5);
        return (0, "split [$s1] [$s2]") unless $s1 eq main::ans(0x00, 0) && $s2 eq 'closed';
        return (1, 'answered before its check field, then closed');
    },
};
