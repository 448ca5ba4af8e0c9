# defect box p12 (see the CATALOGUE.json of its half)
use strict;
use warnings;
+{
    base      => 'legal-p',
    catalogue => {
        class     => 'g',
        clauses   => ['T1', 'A1'],
        mechanism => 'It collects the answers of a connection in a batch that is written when 8 answers are pending or when a 6-second flush timer fires: a lone request (a ping, CycleOn, CycleOff, a single pose) is answered only after 6 s, past time_out, while a 50 Hz stream looks almost fine.',
        keywords  => ['8', 'time_out'],
        trigger   => 'FE FE 00 01 01 00 00 00 00 00 00 00 00 00 alone on a connection: the box answers FE FE 00 01 10 00 00 00 00 00 00 00 00 00 after 6 s; it should answer at once (well within time_out). Eight requests sent together are answered at once.',
        fix       => 'Write each answer as soon as it is ready (flush the batch after every request, or drop the batching).',
        looks_like => 'a CycleOn that waits for the detection to warm up, or a whole box that is slow (the stream hides it)',
    },
    hooks => {
        enqueued => sub {
            my ($c) = @_;
            my $q = $c->{q};
            if (@$q >= 8) { $_->{due} = 0 for @$q; return }
            $q->[-1]{due} = @$q == 1 ? Time::HiRes::time() + 6 : $q->[0]{due};
        },
    },
    check => sub {
        my ($t) = @_;
        my $want = main::ans(0x00, 0);
        my $late = $t->conn;
        my $t0 = Time::HiRes::time();
        $t->put($late, main::plain(0x00));
        my $c = $t->conn;
        my $a1 = $t->ask($c, main::plain(0x00), 1.0);
        return (0, "lone ping within 1 s [$a1]") unless $a1 eq 'silent';
        $t->put($c, main::plain(0x00) x 7);
        for my $i (1 .. 8) {
            my $a = $t->frame_in($c, 0.5);
            return (0, "batch answer $i [$a]") unless $a eq $want;
        }
        my $al = $t->frame_in($late, 7.5 - (Time::HiRes::time() - $t0));
        my $dt = Time::HiRes::time() - $t0;
        return (0, sprintf('lone ping [%s] after %.1fs', $al, $dt)) unless $al eq $want && $dt > 5.5;
        return (1, sprintf('lone ping answered after %.1fs, 8 pings at once', $dt));
    },
};
