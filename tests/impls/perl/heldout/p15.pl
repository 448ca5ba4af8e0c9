# defect box p15 (see the CATALOGUE.json of its half)
use strict;
use warnings;
+{
    base      => 'legal-p',
    catalogue => {
        class     => 'b',
        clauses   => ['F7', 'F4', 'R7'],
        mechanism => 'It reads the received UDP check field little-endian (low byte first) before comparing it with the CRC-16/MODBUS it computes, though it writes its own CRC big-endian: every correctly checked datagram is dropped, and one whose CRC bytes are swapped is answered.',
        keywords  => ['CRC', 'endian'],
        trigger   => 'UDP datagram FE FE 00 01 01 00 00 00 00 00 00 00 63 35: the box drops it; it should answer FE FE 00 01 10 00 00 00 00 00 00 00 + its CRC. FE FE 00 01 01 00 00 00 00 00 00 00 35 63 is answered.',
        fix       => 'Read the check field big-endian, as the box writes it (and as F7 says).',
        looks_like => 'a different CRC algorithm, or a box that does not serve UDP at all',
    },
    hooks => {
        udp_check_ok => sub { my ($body, $chk) = @_; unpack('v', $chk) == main::crc16_modbus($body) },
    },
    check => sub {
        my ($t) = @_;
        my $p = main::plain(0x00, chk => 'crc');
        my $a1 = $t->udp($p, 0.4);
        my $sw = substr($p, 0, 12) . reverse(substr($p, 12, 2));
        my $a2 = $t->udp($sw, 0.5);
        my $want = pack('n n C C C C n n', 0xFEFE, 1, 0x10, 0, 0, 0, 0, 0);
        $want = main::hexs($want . pack('n', main::crc16_modbus($want)));
        return (0, "good CRC [$a1]") unless $a1 eq 'silent';
        return (0, "swapped CRC [$a2]") unless $a2 eq $want;
        return (1, 'right CRC dropped, swapped CRC answered');
    },
};
