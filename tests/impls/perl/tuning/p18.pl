# defect box p18 (see the CATALOGUE.json of its half)
use strict;
use warnings;
my ($leaked, @keep) = (0);
+{
    base      => 'legal-q',
    catalogue => {
        class     => 'i',
        clauses   => ['R5', 'S5', 'R2'],
        mechanism => 'A connection that the robot closes while a partial frame is still in its receive buffer is never freed (its socket and its slot in a 20-entry table stay taken): after 20 such connections every new connection is closed at once; connections closed between frames are freed.',
        keywords  => ['partial frame', 'connection'],
        trigger   => '20 times: connect, send FE FE 00 01 01 (the start of a header), close; then connect and send FE FE 00 01 01 00 00 00 00 00 00 00 00 00: the box closes the new connection without answering; it should answer FE FE 00 01 10 00 00 00 00 00 00 00 00 00.',
        fix       => 'On the robot\'s close, free the connection whatever its receive buffer holds (discard the partial frame).',
        looks_like => 'a table that leaks every closed connection (here only closes in the middle of a frame count)',
    },
    hooks => {
        on_peer_close => sub {
            my ($c) = @_;
            return 0 unless length $c->{buf};
            $leaked++;
            $main::SEL_R->remove($c->{sock});
            $main::SEL_W->remove($c->{sock});
            delete $main::CONN{ $c->{fd} };
            $c->{dead} = 1;
            push @keep, $c->{sock};
            return 1;
        },
        on_accept => sub { $leaked < 20 },
    },
    check => sub {
        my ($t) = @_;
        for (1 .. 45) {    # clean closes do not leak
            my $c = $t->conn or return (0, 'connect');
            close $c->{s};
        }
        my $a0 = $t->req(main::plain(0x00));
        return (0, "after clean closes [$a0]") unless $a0 eq main::ans(0x00, 0);
        for (1 .. 20) {
            my $c = $t->conn or return (0, 'connect');
            $t->put($c, "\xFE\xFE\x00\x01\x01");
            Time::HiRes::sleep(0.01);
            close $c->{s};
        }
        Time::HiRes::sleep(0.3);
        my $a1 = $t->req(main::plain(0x00), 0.5);
        return (0, "after 20 partial closes [$a1]") unless $a1 eq 'closed';
        return (1, 'after 20 closes inside a frame, new connections are closed at once');
    },
};
