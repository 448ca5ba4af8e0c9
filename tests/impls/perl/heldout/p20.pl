# defect box p20 (see the CATALOGUE.json of its half)
use strict;
use warnings;
+{
    base      => 'legal-q',
    catalogue => {
        class     => 'f',
        clauses   => ['S1', 'S2'],
        mechanism => 'It sets a per-connection "cycle done" flag at CycleOff that nothing clears, and closes the connection on a CycleOn that arrives after it: only one CycleOn -> CycleOff pair is served per connection, though a robot may prime several parts in one session.',
        keywords  => ['CycleOn', 'close'],
        trigger   => 'on one connection: CycleOn, CycleOff, then FE FE 00 01 01 01 00 00 00 00 00 00 00 00 (a second CycleOn): the box closes the connection without answering; it should answer FE FE 00 01 10 01 00 00 00 00 00 00 00 00 (or 0001).',
        fix       => 'Clear the cycle state at CycleOff (or do not keep a "done" flag) so that the next CycleOn starts a new cycle.',
        looks_like => 'a box that closes the connection after CycleOff (it closes on the next CycleOn; pings in between are answered)',
    },
    hooks => {
        action => sub {
            my ($c, $h, $data, $default) = @_;
            if ($h->{act} == 0x01 && $c->{cycle_done}) { main::close_conn($c); return }
            my $on = ${ main::cycle_ref($c) };
            $default->();
            $c->{cycle_done} = 1 if $h->{act} == 0x02 && $on;
        },
    },
    check => sub {
        my ($t) = @_;
        my $c = $t->conn;
        my @a = map { $t->ask($c, main::plain($_), 0.5) } (0x01, 0x02, 0x00, 0x01);
        my @w = (main::ans(0x01, 0), main::ans(0x02, 0), main::ans(0x00, 0), 'closed');
        for (0 .. 3) { return (0, "step $_ [$a[$_]]") unless $a[$_] eq $w[$_] }
        my $n = $t->conn;
        my $b = $t->ask($n, main::plain(0x01));
        return (0, "new connection CycleOn [$b]") unless $b eq main::ans(0x01, 0);
        return (1, 'second CycleOn on a connection closes it');
    },
};
