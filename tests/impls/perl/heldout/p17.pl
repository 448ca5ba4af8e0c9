# defect box p17 (see the CATALOGUE.json of its half)
use strict;
use warnings;
+{
    base      => 'legal-q',
    catalogue => {
        class     => 'h',
        clauses   => ['F7'],
        mechanism => 'It computes the CRC of a UDP answer before it writes the error code into it: answers with a non-zero error code (1001, 1002, 0002, FFFF ...) carry the CRC of the same answer with error 0000, so the robot drops them as damaged; 0000 answers are right.',
        keywords  => ['CRC', 'error code'],
        trigger   => 'UDP: a pose whose block has index 00 (this box starts at 01): FE FE 00 01 01 23 01 01 00 19 00 00 00 44480000 C1480000 43AF2000 43340000 00000000 42B40000 + CRC: the box answers FE FE 00 01 10 23 00 00 00 00 10 01 + the CRC of FE FE 00 01 10 23 00 00 00 00 00 00; it should carry the CRC of the answer as sent (with 10 01).',
        fix       => 'Write the error code first, then compute the CRC over the finished answer.',
        looks_like => 'a wrong CRC algorithm or coverage (only the refusals show it)',
    },
    hooks => {
        udp_answer_crc => sub {
            my ($body, $err) = @_;
            my $b = $body;
            substr($b, 10, 2) = "\x00\x00";
            return main::crc16_modbus($b);
        },
    },
    check => sub {
        my ($t) = @_;
        my $a1 = $t->udp(main::pose(0, 1, chk => 'crc'));
        my $a2 = $t->udp(main::pose(1, 1, chk => 'crc'));
        my $mk = sub {
            my ($err, $crcerr) = @_;
            my $h = pack('n n C C C C n n', 0xFEFE, 1, 0x10, 0x23, 0, 0, 0, $err);
            my $hc = pack('n n C C C C n n', 0xFEFE, 1, 0x10, 0x23, 0, 0, 0, $crcerr);
            return main::hexs($h . pack('n', main::crc16_modbus($hc)));
        };
        return (0, "refusal [$a1]") unless $a1 eq $mk->(0x1001, 0);
        return (0, "0000 answer [$a2]") unless $a2 eq $mk->(0, 0);
        return (1, '1001 over UDP carries the CRC of the 0000 answer');
    },
};
