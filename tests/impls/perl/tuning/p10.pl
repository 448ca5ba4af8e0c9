# defect box p10 (see the CATALOGUE.json of its half)
use strict;
use warnings;
+{
    base      => 'legal-p',
    catalogue => {
        class     => 'f',
        clauses   => ['S4', 'E4', 'S1'],
        mechanism => 'It treats the close of a connection that sent poses (the stream, Send_Pos_Off) as the end of the session and closes every other open connection, the command connection included, though the robot keeps it until ISIGHT(2).',
        keywords  => ['stream', 'close'],
        trigger   => 'command connection open; a second connection sends a pose and closes; then FE FE 00 01 01 00 00 00 00 00 00 00 00 00 on the command connection: the box has closed it (no answer, EOF); it should answer FE FE 00 01 10 00 00 00 00 00 00 00 00 00.',
        fix       => 'Close only the connection the robot closed; leave the others alone.',
        looks_like => 'an idle time-out on the command connection, or a result request (27) that is never answered in the E4 session',
    },
    hooks => {
        action => sub {
            my ($c, $h, $data, $default) = @_;
            $c->{sent_pose} = 1 if $h->{act} == 0x23 || $h->{act} == 0x24;
            $default->();
        },
        on_peer_close => sub {
            my ($c) = @_;
            if ($c->{sent_pose}) { main::close_conn($_) for grep { $_ != $c } values %main::CONN }
            return 0;
        },
    },
    check => sub {
        my ($t) = @_;
        my $cmd = $t->conn;
        my $a0 = $t->ask($cmd, main::plain(0x00));
        my $other = $t->conn;
        $t->ask($other, main::plain(0x00));
        close $other->{s};
        Time::HiRes::sleep(0.2);
        my $a1 = $t->ask($cmd, main::plain(0x00));
        my $stream = $t->conn;
        my $sp = $t->ask($stream, main::pose(0, 1));
        close $stream->{s};
        Time::HiRes::sleep(0.2);
        my $a2 = $t->ask($cmd, main::plain(0x00), 0.5);
        return (0, "before [$a0] [$a1] [$sp]") unless $a0 eq main::ans(0x00, 0) && $a1 eq $a0 && $sp eq main::ans(0x23, 0);
        return (0, "after the stream closed [$a2]") unless $a2 eq 'closed';
        return (1, 'command connection closed with the stream');
    },
};
