# defect box p16 (see the CATALOGUE.json of its half)
use strict;
use warnings;
my $buf = "\x00" x 6400;    # the reused receive buffer
+{
    base      => 'legal-p',
    catalogue => {
        class     => 'h',
        clauses   => ['F7', 'R7'],
        mechanism => 'It copies each datagram into a reused receive buffer and checks only that the datagram is not longer than the frame its header announces, never that it is as long: a short datagram is completed with the bytes the previous datagram left in the buffer, so a truncated copy of the last frame passes the CRC and is answered 0000.',
        keywords  => ['length', 'previous'],
        trigger   => 'UDP: a pose datagram with 2 blocks (FE FE 00 01 01 23 01 02 00 19 00 00 ... + CRC, 64 bytes), then the same datagram without its last 3 bytes (61 bytes): the box answers the short one FE FE 00 01 10 23 00 00 00 00 00 00 + CRC; it should drop it silently (it is not one frame long).',
        fix       => 'Drop a datagram whose length is not exactly 12 + N*L + 2 (and clear the buffer, or parse from the datagram itself).',
        looks_like => 'a box that does not verify the CRC (a short datagram sent first is dropped)',
    },
    hooks => {
        udp_frame => sub {
            my ($d) = @_;
            return undef if length($d) < 12 || length($d) > length($buf);
            substr($buf, 0, length $d) = $d;
            my $h = main::hdr_fields($buf);
            my $flen = 14 + $h->{n} * $h->{l};
            return undef if length($d) > $flen || $flen > length($buf);
            my $body = substr($buf, 0, $flen - 2);
            return undef unless unpack('n', substr($buf, $flen - 2, 2)) == main::crc16_modbus($body);
            return substr($buf, 0, $flen);
        },
    },
    check => sub {
        my ($t) = @_;
        my $up = main::pose(0, 2, chk => 'crc');
        my $short = substr($up, 0, length($up) - 3);
        my $a0 = $t->udp(main::pose(0, 3, chk => 'crc'));
        my $a1 = $t->udp($up);
        my $a2 = $t->udp($short);
        my $want = pack('n n C C C C n n', 0xFEFE, 1, 0x10, 0x23, 0, 0, 0, 0);
        $want = main::hexs($want . pack('n', main::crc16_modbus($want)));
        my $a3 = $t->udp(main::pose(0, 2, chk => 'crc') . "\x00", 0.3);
        return (0, "whole [$a1]") unless $a1 eq $want && $a0 eq $want;
        return (0, "short [$a2]") unless $a2 eq $want;
        return (0, "long [$a3]") unless $a3 eq 'silent';
        return (1, 'a short datagram completed from the previous one is answered 0000');
    },
};
