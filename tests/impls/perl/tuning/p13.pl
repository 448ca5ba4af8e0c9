# defect box p13 (see the CATALOGUE.json of its half)
use strict;
use warnings;
+{
    base      => 'legal-p',
    catalogue => {
        class     => 'a',
        clauses   => ['F1', 'R1'],
        mechanism => 'It checks only the first byte of the start word: a header beginning FE 00, FE FF or any FE xx is taken as a frame and answered like a request.',
        keywords  => ['start word', 'second byte'],
        trigger   => 'FE FF 00 01 01 00 00 00 00 00 00 00 00 00: the box answers FE FE 00 01 10 00 00 00 00 00 00 00 00 00; it should not answer 0000 (silence, as it does for other garbage).',
        fix       => 'Compare both bytes of the start word with FE FE.',
        looks_like => 'a box that does not check the start word at all (it does, for bytes other than FE)',
    },
    hooks => { start_ok => sub { length($_[0]) >= 2 && ord($_[0]) == 0xFE } },
    check => sub {
        my ($t) = @_;
        my $a1 = $t->req(main::plain(0x00, sw => 0xFEFF));
        my $a2 = $t->req(main::plain(0x00, sw => 0xEEFE), 0.3);
        return (0, "FE FF [$a1]") unless $a1 eq main::ans(0x00, 0);
        return (0, "EE FE [$a2]") unless $a2 eq 'silent';
        return (1, 'FE FF header answered 0000');
    },
};
