#!/usr/bin/perl
# Self-check of the Perl boxes: starts every box (or those named), runs a short
# conformance script against the legal boxes and each defect's trigger against
# its box, prints one line per box, exits non-zero on any failure.
# Every read has a timeout; every box is killed at the end.  Loopback only.
use strict;
use warnings;
use IO::Socket::INET;
use IO::Select;
use Socket qw(IPPROTO_TCP TCP_NODELAY);
use Time::HiRes qw(time sleep);
use POSIX qw(WNOHANG);
use File::Basename qw(dirname);
use File::Spec;
use File::Temp qw(tempfile);

our $DIR = File::Spec->rel2abs(dirname(__FILE__));
require "$DIR/box.pl";    # for %LEGAL, the codec and the box lookup (main() is not run)
our %LEGAL;

$SIG{PIPE} = 'IGNORE';

# ---------------------------------------------------------------- frames
sub hexs { join ' ', map { sprintf '%02X', $_ } unpack 'C*', $_[0] }
sub unhex { my $h = shift; $h =~ s/\s+//g; pack 'H*', $h }

sub frame {
    my (%o) = @_;
    my $data = $o{data} // '';
    my $body = pack('n n C C C C n n', $o{sw} // 0xFEFE, $o{ver} // 1, $o{tt} // 1, $o{act} // 0,
        $o{bt} // 0, $o{n} // 0, $o{l} // 0, $o{err} // 0) . $data;
    my $chk = $o{chk} // 0;
    $chk = main::crc16_modbus($body) if $chk eq 'crc';
    return $body . pack('n', $chk);
}

sub pose_data {    # n pose blocks from index $first
    my ($first, $n, @v) = @_;
    @v = (800, -12.5, 350.25, 180, 0, 90) unless @v;
    return join '', map { pack('C f>6', ($first + $_) & 0xFF, @v) } 0 .. $n - 1;
}
sub tol_data { my ($first, $n, $v) = @_; join '', map { pack('C f>', ($first + $_) & 0xFF, $v // 0.5) } 0 .. $n - 1 }

sub pose  { my ($fi, $n, %o) = @_; frame(act => 0x23, bt => 1, n => $n, l => 25, data => pose_data($fi, $n), %o) }
sub tol   { my ($fi, $n, %o) = @_; frame(act => 0x25, bt => 2, n => $n, l => 5, data => tol_data($fi, $n), %o) }
sub plain { my ($act, %o) = @_; frame(act => $act, %o) }

sub ans {    # the expected TCP answer, as hex
    my ($act, $err, $blk) = @_;
    my $b = defined $blk
        ? pack('n n C C C C n n', 0xFEFE, 1, 0x10, $act, 3, 1, 5, $err) . $blk
        : pack('n n C C C C n n', 0xFEFE, 1, 0x10, $act, 0, 0, 0, $err);
    return hexs($b . "\x00\x00");
}

# ---------------------------------------------------------------- a tiny robot
package T;
use Time::HiRes qw(time sleep);

sub new { my ($cls, %b) = @_; bless {%b}, $cls }

sub conn {
    my ($t) = @_;
    my $s = IO::Socket::INET->new(PeerAddr => '127.0.0.1', PeerPort => $t->{port}, Proto => 'tcp', Timeout => 2)
        or return undef;
    setsockopt($s, Socket::IPPROTO_TCP(), Socket::TCP_NODELAY(), 1);
    return { s => $s, buf => '' };
}

sub put {    # send, optionally in pieces: put($c, $bytes, [$size, $pause])
    my ($t, $c, $bytes, $size, $pause) = @_;
    $size ||= length($bytes) || 1;
    for (my $o = 0; $o < length $bytes; $o += $size) {
        my $w = eval { syswrite($c->{s}, substr($bytes, $o, $size)) };
        return 0 unless $w;
        sleep($pause) if $pause && $o + $size < length $bytes;
    }
    return 1;
}

sub fill {    # read until buf has $n bytes or the deadline passes; 'closed' on EOF
    my ($t, $c, $n, $deadline) = @_;
    my $sel = IO::Select->new($c->{s});
    while (length($c->{buf}) < $n) {
        my $left = $deadline - time;
        return 'silent' if $left <= 0;
        next unless $sel->can_read($left);
        my $r = sysread($c->{s}, my $chunk, 65536);
        return 'closed' unless $r;
        $c->{buf} .= $chunk;
    }
    return 'ok';
}

sub frame_in {    # one answer frame as hex, or 'silent' / 'closed'; garbage before FE FE is kept as '?' prefix
    my ($t, $c, $timeout) = @_;
    my $deadline = time + ($timeout // 1.0);
    my $st = $t->fill($c, 12, $deadline);
    return $st unless $st eq 'ok';
    my $junk = '';
    while (substr($c->{buf}, 0, 2) ne "\xFE\xFE") {
        $junk .= substr($c->{buf}, 0, 1, '');
        $st = $t->fill($c, 12, $deadline);
        return $st unless $st eq 'ok';
    }
    my (undef, undef, undef, undef, undef, $n, $l) = unpack('n n C C C C n', $c->{buf});
    my $need = 12 + $n * $l + 2;
    $st = $t->fill($c, $need, $deadline);
    return $st unless $st eq 'ok';
    my $f = substr($c->{buf}, 0, $need, '');
    return (length $junk ? '? ' . main::hexs($junk) . ' | ' : '') . main::hexs($f);
}

sub ask {    # send on $c, read one answer
    my ($t, $c, $bytes, $timeout, @piece) = @_;
    $t->put($c, $bytes, @piece) or return 'closed';
    return $t->frame_in($c, $timeout);
}

sub req {    # one request on a fresh connection
    my ($t, $bytes, $timeout, @piece) = @_;
    my $c = $t->conn or return 'noconnect';
    my $r = $t->ask($c, $bytes, $timeout, @piece);
    close $c->{s};
    return $r;
}

sub udp {    # one datagram, its answer as hex or 'silent'
    my ($t, $bytes, $timeout) = @_;
    my $u = IO::Socket::INET->new(PeerAddr => '127.0.0.1', PeerPort => $t->{uport}, Proto => 'udp') or return 'nosock';
    send($u, $bytes, 0);
    my $sel = IO::Select->new($u);
    return 'silent' unless $sel->can_read($timeout // 0.5);
    my $d = '';
    $u->recv($d, 65536);
    return main::hexs($d);
}

package main;

# ---------------------------------------------------------------- box processes
sub start_box {
    my ($name) = @_;
    my ($efh, $efile) = tempfile('perlbox-XXXXXX', TMPDIR => 1, UNLINK => 1);
    pipe(my $rd, my $wr) or die "pipe: $!";
    my $pid = fork // die "fork: $!";
    if (!$pid) {
        close $rd;
        open(STDOUT, '>&', $wr) or die;
        open(STDERR, '>&', $efh) or die;
        exec($^X, "$DIR/box.pl", $name, '--port', '0') or exit 127;
    }
    close $wr;
    my $sel = IO::Select->new($rd);
    my $line = '';
    my $deadline = time + 5;
    while ($line !~ /\n/ && time < $deadline) {
        last unless $sel->can_read($deadline - time);
        my $r = sysread($rd, my $ch, 1) or last;
        $line .= $ch;
    }
    my %b = (name => $name, pid => $pid, pipe => $rd, efile => $efile, line => $line);
    if ($line =~ /^listening tcp 127\.0\.0\.1:(\d+) udp 127\.0\.0\.1:(\d+)(?: args (.*))?\n$/) {
        @b{qw(port uport args)} = ($1, $2, $3 // '');
    }
    return \%b;
}

sub stop_box {    # SIGTERM, bounded wait; returns the exit status or 'killed'
    my ($b) = @_;
    kill 'TERM', $b->{pid};
    my $deadline = time + 3;
    while (time < $deadline) {
        my $w = waitpid($b->{pid}, WNOHANG);
        return $? >> 8 if $w == $b->{pid};
        sleep 0.02;
    }
    kill 'KILL', $b->{pid};
    waitpid($b->{pid}, 0);
    return 'killed';
}

# ---------------------------------------------------------------- the legal script
sub legal_script {
    my ($t, $cfg) = @_;
    my $fi = $cfg->{first_index};
    my @fail;
    my $chk = sub { my ($what, $got, $want) = @_; push @fail, "$what: got [$got] want [$want]" unless $got eq $want };
    my $not0000 = sub {    # silence, close or a non-zero error
        my ($what, $got) = @_;
        push @fail, "$what: answered 0000 [$got]" if $got =~ /^FE FE 00 01 10 .. .. .. .. .. 00 00/;
    };

    $chk->('ping', $t->req(plain(0x00)), ans(0x00, 0));
    $chk->('pose', $t->req(pose($fi, 1)), ans(0x23, 0));
    $chk->('register pose x2', $t->req(frame(act => 0x24, bt => 1, n => 2, l => 25, data => pose_data($fi, 2))), ans(0x24, 0));
    $chk->('tolerance x3', $t->req(tol($fi, 3)), ans(0x25, 0));
    $chk->('pose x255', $t->req(pose($fi, 255)), ans(0x23, 0));
    $chk->('tolerance crc in check', $t->req(tol($fi, 1, chk => 'crc')), ans(0x25, 0));
    $chk->('pose wrong first index', $t->req(pose($fi ? 0 : 1, 1)), ans(0x23, 0x1001));
    $chk->('pose NaN', $t->req(frame(act => 0x23, bt => 1, n => 1, l => 25,
        data => pack('C', $fi) . pack('f>5', 1, 2, 3, 4, 5) . "\x7F\xC0\x00\x00")), ans(0x23, 0x1001));
    $chk->('pose L=24', $t->req(frame(act => 0x23, bt => 1, n => 1, l => 24, data => substr(pose_data($fi, 1), 0, 24))),
        ans(0x23, 0x1001));
    $chk->('tolerance type 01', $t->req(frame(act => 0x25, bt => 1, n => 1, l => 5, data => tol_data($fi, 1))),
        ans(0x25, 0x1002));
    $chk->('pose N=0', $t->req(frame(act => 0x23, bt => 1, n => 0, l => 25)), ans(0x23, 0x1001));
    $not0000->('version 00 02', $t->req(plain(0x00, ver => 2), 0.3));
    $not0000->('transfer type 10', $t->req(plain(0x00, tt => 0x10), 0.3));
    $not0000->('start word FE FF', $t->req(plain(0x00, sw => 0xFEFF), 0.3));
    $not0000->('unknown action 30', $t->req(plain(0x30), 0.3));
    $chk->('pose one byte per segment', $t->req(pose($fi, 1), 1.5, 1, 0.005), ans(0x23, 0));

    my $c = $t->conn;
    $t->put($c, plain(0x00) . pose($fi, 1) . tol($fi, 2));
    $chk->('3 in one segment #1', $t->frame_in($c), ans(0x00, 0));
    $chk->('3 in one segment #2', $t->frame_in($c), ans(0x23, 0));
    $chk->('3 in one segment #3', $t->frame_in($c), ans(0x25, 0));
    # the canonical session, with a stream connection and a hanging partial frame elsewhere
    my $hang = $t->conn;
    $t->put($hang, substr(pose($fi, 1), 0, 20));
    my $stream = $t->conn;
    $chk->('stream pose before CycleOn', $t->ask($stream, pose($fi, 1)), ans(0x23, 0));
    $chk->('CycleOn', $t->ask($c, plain(0x01)), ans(0x01, 0));
    $t->put($stream, pose($fi, 1) x 20);
    $chk->("stream pose $_", $t->frame_in($stream), ans(0x23, 0)) for 1 .. 20;
    $chk->('pose on command connection', $t->ask($c, pose($fi, 1)), ans(0x23, 0));
    $chk->('CycleOff', $t->ask($c, plain(0x02)), ans(0x02, 0));
    $chk->('second CycleOn', $t->ask($c, plain(0x01)), ans(0x01, 0));
    $chk->('second CycleOff', $t->ask($c, plain(0x02)), ans(0x02, 0));
    close $stream->{s};
    if ($cfg->{extension}) {
        $chk->('ProgIdx 3', $t->ask($c, frame(act => 0x26, bt => 3, n => 1, l => 5, data => pack('C l>', $fi, 3))),
            ans(0x26, 0, pack('C l>', $fi, 3)));
        $chk->('ProgIdx -70000', $t->ask($c, frame(act => 0x26, bt => 3, n => 1, l => 5, data => pack('C l>', $fi, -70000))),
            ans(0x26, 0, pack('C l>', $fi, -70000)));
        my $r = $t->ask($c, plain(0x27));
        push @fail, "result request: [$r]" unless $r =~ /^FE FE 00 01 10 27 03 01 00 05 00 00 .. 00 00 (00 (01|02|0A|14|CA)|01 99) 00 00$/;
    } else {
        $not0000->('27 without extension', $t->ask($c, plain(0x27), 0.3));
    }
    $chk->('ping after session', $t->ask($c, plain(0x00)), ans(0x00, 0));
    close $c->{s};
    close $hang->{s};

    # UDP
    my $u = plain(0x00, chk => 'crc');
    $chk->('udp example', hexs($u), 'FE FE 00 01 01 00 00 00 00 00 00 00 63 35');
    my $want = pack('n n C C C C n n', 0xFEFE, 1, 0x10, 0, 0, 0, 0, 0);
    $chk->('udp ping', $t->udp($u), hexs($want . pack('n', crc16_modbus($want))));
    my $up = pose($fi, 2, chk => 'crc');
    $want = pack('n n C C C C n n', 0xFEFE, 1, 0x10, 0x23, 0, 0, 0, 0);
    $chk->('udp pose', $t->udp($up), hexs($want . pack('n', crc16_modbus($want))));
    my $bad = $up;
    substr($bad, 20, 1) = "\x55";
    $chk->('udp damaged pose', $t->udp($bad, 0.3), 'silent');
    $chk->('udp trailing byte', $t->udp($u . "\x00", 0.3), 'silent');
    $chk->('udp short', $t->udp(substr($up, 0, length($up) - 3), 0.3), 'silent');
    $chk->('ping at the end', $t->req(plain(0x00)), ans(0x00, 0));
    return @fail;
}

# ---------------------------------------------------------------- run
my @names = @ARGV ? @ARGV : do { my @n = `$^X $DIR/box.pl --list`; chomp @n; @n };
my $t0 = time;
my $bad = 0;
for my $name (@names) {
    my $start = time;
    my ($base, $check, $cfg);
    if ($LEGAL{$name}) {
        $base = $name;
    } else {
        my $f = defect_file($name);
        my $d = $f ? do $f : undef;
        if (!$d) { print "FAIL $name: cannot load\n"; $bad++; next }
        $base  = $d->{base};
        $check = $d->{check};
    }
    $cfg = $LEGAL{$base};
    my $b = start_box($name);
    if (!$b->{port}) {
        print "FAIL $name: first line [$b->{line}]\n";
        $bad++;
        stop_box($b);
        next;
    }
    my $t = T->new(port => $b->{port}, uport => $b->{uport}, cfg => $cfg, fi => $cfg->{first_index});
    my @fail;
    my $want_args = join ' ', @{ $cfg->{args} };
    push @fail, "args [$b->{args}] want [$want_args]" unless $b->{args} eq $want_args;
    if ($check) {
        my ($ok, $msg) = eval { $check->($t) };
        ($ok, $msg) = (0, "check died: $@") if $@;
        push @fail, "trigger not shown: $msg" unless $ok;
        $msg //= '';
        $b->{note} = $msg;
    } else {
        push @fail, legal_script($t, $cfg);
    }
    my $st = stop_box($b);
    push @fail, "exit status $st" unless $st eq '0';
    my $err = do { local $/; open my $fh, '<', $b->{efile}; <$fh> } // '';
    push @fail, "stderr: " . substr($err, 0, 200) if length $err;
    my $dt = sprintf '%.1fs', time - $start;
    if (@fail) { $bad++; print "FAIL $name ($dt): ", join('; ', @fail), "\n" }
    else       { print "PASS $name ($dt)", ($b->{note} ? ": $b->{note}" : ''), "\n" }
}
printf "%d box(es), %d failed, %.1fs\n", scalar @names, $bad, time - $t0;
exit($bad ? 1 : 0);
