# defect box p05 (see the CATALOGUE.json of its half)
use strict;
use warnings;
+{
    base      => 'legal-p',
    catalogue => {
        class     => 'i',
        clauses   => ['R5', 'R2', 'S5'],
        mechanism => 'When 100 connections are open at once it takes the listening socket out of its poll set to shed load, and the code that should put it back never runs: from then on no new connection is accepted, even after the others have closed.',
        keywords  => ['100', 'accept'],
        trigger   => 'open 100 connections, close them, then connect and send FE FE 00 01 01 00 00 00 00 00 00 00 00 00: the box never answers (the connection sits in the kernel backlog, never accepted); it should answer FE FE 00 01 10 00 00 00 00 00 00 00 00 00.',
        fix       => 'Put the listening socket back into the poll set as soon as the number of open connections falls below the limit (or do not remove it at all).',
        looks_like => 'a connection table that leaks closed connections (new connections die after many connect/disconnect cycles)',
    },
    hooks => {
        on_accept => sub {
            $main::SEL_R->remove($main::LISTEN) if scalar(keys %main::CONN) + 1 >= 100;
            return 1;
        },
    },
    check => sub {
        my ($t) = @_;
        my $p0 = $t->req(main::plain(0x00));
        return (0, "first ping [$p0]") unless $p0 eq main::ans(0x00, 0);
        my @c = map { $t->conn } 1 .. 100;
        Time::HiRes::sleep(0.3);
        close $_->{s} for grep {defined} @c;
        Time::HiRes::sleep(0.3);
        my $p1 = $t->req(main::plain(0x00), 1.0);
        return (0, "ping after 100 connections [$p1]") unless $p1 eq 'silent';
        return (1, 'after 100 simultaneous connections, new connections are never served');
    },
};
