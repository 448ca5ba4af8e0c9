#!/usr/bin/perl
# An independent iSight AI Box (server), written from docs/PROTOCOL.md and
# docs/LEGAL-CHOICES.md alone.  Perl 5, core modules only.
#
#   perl box.pl NAME --port 0     serve box NAME on 127.0.0.1
#   perl box.pl --list            every box name
#
# One process, one thread: an IO::Select loop serves every TCP connection and
# the UDP socket.  Legal choices are configuration (%LEGAL); a defect box is a
# legal box plus hooks loaded from tuning/NAME.pl, heldout/NAME.pl or defects/NAME.pl.
use strict;
use warnings;
use IO::Socket::INET;
use IO::Select;
use Socket qw(IPPROTO_TCP TCP_NODELAY);
use Time::HiRes qw(time);
use POSIX qw(EWOULDBLOCK EAGAIN EINTR);
use File::Basename qw(dirname);
use File::Spec;
use Getopt::Long qw(GetOptionsFromArray);

our $DIR = File::Spec->rel2abs(dirname(__FILE__));

# ---------------------------------------------------------------- legal boxes
our %LEGAL = (
    'legal-p' => {
        first_index         => 0,
        framing_garbage     => 'scan',
        framing_version     => 'resume+1',
        framing_length      => 'resume+1',
        framing_transfer    => 'resume+1',
        framing_action      => 'trust',
        framing_shape       => 'trust',
        not_request         => 'silent',
        refusal_action      => 'echo',
        refusal_code        => 0xFFFF,
        malformed_blockless => 'error',
        malformed_ext       => 'silent',
        request_error_field => 'accept',
        tcp_check           => 'ignore',
        cycle_scope         => 'box',
        cycle_on_twice      => 0x0000,
        cycle_off_idle      => 0x0000,
        extension           => 1,
        prog_idx            => 'index',
        vision_result       => 1,
        nan                 => 'reject',
        latency_ms          => 0,
        args                => [],
    },
    'legal-q' => {
        first_index         => 1,
        framing_garbage     => 'close',
        framing_version     => 'close',
        framing_length      => 'close',
        framing_transfer    => 'trust',
        framing_action      => 'trust',
        framing_shape       => 'resume+1',
        not_request         => 'error',
        refusal_action      => 'echo',
        refusal_code        => 0xFFFF,
        malformed_blockless => 'silent',
        malformed_ext       => 'silent',
        request_error_field => 'reject',
        tcp_check           => 'zero-or-crc',
        cycle_scope         => 'connection',
        cycle_on_twice      => 0x0001,
        cycle_off_idle      => 0x0002,
        extension           => 0,
        prog_idx            => 'index',
        vision_result       => 1,
        nan                 => 'reject',
        latency_ms          => 20,
        args                => ['--first-index', '1'],
    },
);

our $MAX_BLOCK_BYTES = 255 * 25;    # the largest legal frame: 255 pose blocks

# ---------------------------------------------------------------- box lookup
sub defect_file {
    my ($name) = @_;
    return undef unless $name =~ /^[A-Za-z0-9_-]+$/;
    for my $d (qw(tuning heldout defects)) {
        my $f = "$DIR/$d/$name.pl";
        return $f if -f $f;
    }
    return undef;
}

sub all_names {
    my @n = sort keys %LEGAL;
    my %seen;
    for my $d (qw(tuning heldout defects)) {
        opendir(my $dh, "$DIR/$d") or next;
        for my $f (sort readdir $dh) {
            next unless $f =~ /^(.+)\.pl$/;
            push @n, $1 unless $seen{$1}++;
        }
        closedir $dh;
    }
    return ((sort keys %LEGAL), sort grep { !$LEGAL{$_} } @n);
}

our ($C, %H);     # the box's configuration and its defect hooks

sub load_box {
    my ($name) = @_;
    if ($LEGAL{$name}) {
        $C = { %{ $LEGAL{$name} } };
        return 1;
    }
    my $f = defect_file($name) or return 0;
    my $d = do $f;
    die "cannot load $f: " . ($@ || $!) . "\n" unless ref $d eq 'HASH';
    $C = { %{ $LEGAL{ $d->{base} } } };
    %H = %{ $d->{hooks} || {} };
    return 1;
}

# ---------------------------------------------------------------- codec
sub crc16_modbus {
    my $crc = 0xFFFF;
    for my $c (unpack 'C*', $_[0]) {
        $crc ^= $c;
        for (1 .. 8) { $crc = ($crc & 1) ? (($crc >> 1) ^ 0xA001) : ($crc >> 1) }
    }
    return $crc;
}

sub hdr_fields {
    my ($sw, $ver, $tt, $act, $bt, $n, $l, $err) = unpack('n n C C C C n n', $_[0]);
    return { sw => $sw, ver => $ver, tt => $tt, act => $act, bt => $bt, n => $n, l => $l, err => $err };
}

sub known_action {
    my ($a) = @_;
    return 1 if $a == 0x00 || $a == 0x01 || $a == 0x02 || $a == 0x23 || $a == 0x24 || $a == 0x25;
    return 1 if $C->{extension} && ($a == 0x26 || $a == 0x27);
    return 0;
}

sub shape_ok {
    my ($act, $bt, $n, $l) = @_;
    return $H{shape_ok}->($act, $bt, $n, $l) if $H{shape_ok};
    return base_shape_ok($act, $bt, $n, $l);
}

sub base_shape_ok {
    my ($act, $bt, $n, $l) = @_;
    return ($bt == 0 && $n == 0 && $l == 0) if $act <= 0x02 || $act == 0x27;
    return ($bt == 1 && $n >= 1 && $l == 25) if $act == 0x23 || $act == 0x24;
    return ($bt == 2 && $n >= 1 && $l == 5) if $act == 0x25;
    return ($bt == 3 && $n == 1 && $l == 5) if $act == 0x26;
    return 0;
}

sub finite32 {    # a big-endian binary32 whose exponent is not all ones
    my $u = unpack('N', $_[0]);
    return (($u >> 23) & 0xFF) != 0xFF;
}

sub build_answer {
    my ($act, $err, $bt, $n, $l, $data) = @_;
    return $H{build_answer}->(@_) if $H{build_answer};
    return base_answer(@_);
}

sub base_answer {
    my ($act, $err, $bt, $n, $l, $data) = @_;
    return pack('n n C C C C n n', 0xFEFE, 1, 0x10, $act, $bt // 0, $n // 0, $l // 0, $err)
        . ($data // '') . "\x00\x00";
}

# ---------------------------------------------------------------- state
our %BOX = (cycle => 0, started => time);
our ($SEL_R, $SEL_W, $LISTEN, $UDP);
our %CONN;        # fileno => connection
our %UDPPEER;     # peer address => pseudo connection (cycle state per peer)

sub cycle_ref {
    my ($c) = @_;
    return $C->{cycle_scope} eq 'connection' ? \$c->{cycle} : \$BOX{cycle};
}

# ---------------------------------------------------------------- answers
sub send_raw {
    my ($c, $bytes) = @_;
    if ($c->{udp}) {
        send($UDP, $bytes, 0, $c->{peer});
        return;
    }
    return if $c->{dead};
    $bytes = $H{tcp_out}->($bytes) if $H{tcp_out};
    push @{ $c->{q} }, { due => time + ($C->{latency_ms} || 0) / 1000, bytes => $bytes };
    $H{enqueued}->($c) if $H{enqueued};
    pump($c);
}

sub answer {
    my ($c, $act, $err, $bt, $n, $l, $data) = @_;
    my $a = build_answer($act, $err, $bt, $n, $l, $data);
    if ($c->{udp}) {
        my $body = substr($a, 0, length($a) - 2);
        my $crc = $H{udp_answer_crc} ? $H{udp_answer_crc}->($body, $err) : crc16_modbus($body);
        $a = $body . pack('n', $crc);
    }
    send_raw($c, $a);
}

sub refuse {    # a frame that is not a request, or a malformed blockless one
    my ($c, $act, $code) = @_;
    answer($c, $C->{refusal_action} eq 'echo' ? $act : 0x00, $code // $C->{refusal_code});
}

sub pump {      # move due answers to the output buffer and write what we can
    my ($c) = @_;
    return if $c->{dead} || $c->{udp};
    my $now = time;
    while (@{ $c->{q} } && $c->{q}[0]{due} <= $now + 0.0005) {
        $c->{out} .= (shift @{ $c->{q} })->{bytes};
    }
    if (length $c->{out}) {
        my $w = syswrite($c->{sock}, $c->{out});
        if (defined $w) {
            substr($c->{out}, 0, $w, '');
        } elsif ($! != EWOULDBLOCK && $! != EAGAIN && $! != EINTR) {
            drop_conn($c);
            return;
        }
    }
    if (length $c->{out}) { $SEL_W->add($c->{sock}) unless $SEL_W->exists($c->{sock}) }
    else                  { $SEL_W->remove($c->{sock}) if $SEL_W->exists($c->{sock}) }
    # R5: a robot that sends without reading its answers is not read any further
    # until they drain (bounded memory per connection)
    if (!$c->{closing}) {
        my $full = length($c->{out}) > (1 << 20);
        if    ($full && !$c->{paused}) { $c->{paused} = 1; $SEL_R->remove($c->{sock}) }
        elsif (!$full && $c->{paused}) { $c->{paused} = 0; $SEL_R->add($c->{sock}) }
    }
    if ($c->{closing} && !length($c->{out}) && !@{ $c->{q} }) { drop_conn($c) }
}

sub drop_conn {
    my ($c) = @_;
    return if $c->{dead};
    $c->{dead} = 1;
    $SEL_R->remove($c->{sock});
    $SEL_W->remove($c->{sock});
    delete $CONN{ $c->{fd} };
    close $c->{sock};
}

sub close_conn {    # close after the answers already due are written
    my ($c) = @_;
    return if $c->{udp};
    $c->{closing} = 1;
    $c->{buf} = '';
    $SEL_R->remove($c->{sock});
    $_->{due} = 0 for @{ $c->{q} };
    pump($c);
}

# ---------------------------------------------------------------- requests
sub malformed {
    my ($c, $act) = @_;
    if ($act == 0x23 || $act == 0x24) { answer($c, $act, 0x1001); return }
    if ($act == 0x25)                 { answer($c, $act, 0x1002); return }
    if ($act == 0x26 || $act == 0x27) {
        return if $C->{malformed_ext} eq 'silent';
        answer($c, $act, 400, 3, 1, 5, pack('C N', $C->{first_index}, 400));
        return;
    }
    my $m = $C->{malformed_blockless};
    if    ($m eq 'silent') { }
    elsif ($m eq 'close')  { close_conn($c) }
    else { refuse($c, $act, $act == 0x01 ? 0x0001 : $act == 0x02 ? 0x0002 : 0xFFFF) }
}

sub not_request {
    my ($c, $act) = @_;
    my $m = $C->{not_request};
    if    ($m eq 'silent') { }
    elsif ($m eq 'close')  { close_conn($c) }
    else                   { refuse($c, $act) }
}

sub well_formed {
    my ($c, $h, $frame) = @_;
    return 0 unless shape_ok($h->{act}, $h->{bt}, $h->{n}, $h->{l});
    return 0 if $h->{err} != 0 && $C->{request_error_field} eq 'reject';
    my $blen = $h->{n} * $h->{l};
    if (!$c->{udp} && $C->{tcp_check} eq 'zero-or-crc') {
        my $chk = unpack('n', substr($frame, 12 + $blen, 2));
        return 0 unless $chk == 0 || $chk == crc16_modbus(substr($frame, 0, 12 + $blen));
    }
    for my $i (0 .. $h->{n} - 1) {
        my $blk = substr($frame, 12 + $i * $h->{l}, $h->{l});
        return 0 unless ord($blk) == (($C->{first_index} + $i) & 0xFF);
        if ($h->{bt} == 1 || $h->{bt} == 2) {
            next unless $C->{nan} eq 'reject';
            for (my $o = 1; $o < length $blk; $o += 4) {
                return 0 unless finite32(substr($blk, $o, 4));
            }
        }
    }
    return 1;
}

sub handle_frame {
    my ($c, $frame) = @_;
    my $h = hdr_fields($frame);
    if ($h->{tt} != 0x01 || !known_action($h->{act})) { not_request($c, $h->{act}); return }
    if (!well_formed($c, $h, $frame)) { malformed($c, $h->{act}); return }
    my $data = substr($frame, 12, $h->{n} * $h->{l});
    my $default = sub { do_action($c, $h, $data) };
    if ($H{action}) { $H{action}->($c, $h, $data, $default) }
    else            { $default->() }
}

sub do_action {
    my ($c, $h, $data) = @_;
    my $act = $h->{act};
    if ($act == 0x00) { answer($c, 0x00, 0x0000); return }
    if ($act == 0x01) {
        my $cy = cycle_ref($c);
        if ($$cy) { answer($c, 0x01, $C->{cycle_on_twice}); return }
        $$cy = 1;
        answer($c, 0x01, 0x0000);
        return;
    }
    if ($act == 0x02) {
        my $cy = cycle_ref($c);
        if (!$$cy) { answer($c, 0x02, $C->{cycle_off_idle}); return }
        $$cy = 0;
        answer($c, 0x02, 0x0000);
        return;
    }
    if ($act == 0x23 || $act == 0x24) { answer($c, $act, 0x0000); return }
    if ($act == 0x25) { answer($c, $act, 0x0000); return }
    if ($act == 0x26) {
        my $raw = substr($data, 1, 4);
        my $v = $H{progidx_value} ? $H{progidx_value}->($raw) : unpack('l>', $raw);
        $v = 409 if $C->{prog_idx} eq '409';
        answer($c, 0x26, 0x0000, 3, 1, 5, pack('C l>', ord($data), $v));
        return;
    }
    if ($act == 0x27) {
        answer($c, 0x27, 0x0000, 3, 1, 5, pack('C l>', $C->{first_index}, $C->{vision_result}));
        return;
    }
}

# ---------------------------------------------------------------- TCP framing
sub reject_header {    # R6 (b) resume+k, or (c) close
    my ($c, $kind) = @_;
    my $p = $C->{"framing_$kind"};
    if ($p eq 'close') { close_conn($c); return 0 }
    my ($k) = $p =~ /^resume\+(\d+)$/ or die "bad policy $p\n";
    substr($c->{buf}, 0, $k, '');
    $c->{scanning} = 1;
    return 1;
}

sub start_ok {
    return $H{start_ok}->($_[0]) if $H{start_ok};
    return substr($_[0], 0, 2) eq "\xFE\xFE";
}

sub process {
    my ($c) = @_;
    while (!$c->{closing} && !$c->{dead}) {
        my $b = \$c->{buf};
        if ($c->{skip}) {    # counting away a frame too large to buffer
            my $k = $c->{skip} < length($$b) ? $c->{skip} : length($$b);
            substr($$b, 0, $k, '');
            $c->{skip} -= $k;
            last if $c->{skip};
            next;
        }
        last if $$b eq '';
        if (length($$b) < 2 && $$b eq "\xFE" && !$H{drop_partial_start}) { last }
        if (!start_ok($$b)) {
            if ($c->{scanning} || $C->{framing_garbage} eq 'scan') {
                my $i = index($$b, "\xFE\xFE", 1);
                if ($i < 0) {
                    $$b = (!$H{drop_partial_start} && substr($$b, -1) eq "\xFE") ? "\xFE" : '';
                    $c->{scanning} = 1;
                    last;
                }
                substr($$b, 0, $i, '');
                $c->{scanning} = 1;
                next;
            }
            close_conn($c);
            last;
        }
        last if length($$b) < 12;
        my $h = hdr_fields($$b);
        if ($h->{ver} != 0x0001) { reject_header($c, 'version') ? next : last }
        my $blen = $h->{n} * $h->{l};
        if ($blen > $MAX_BLOCK_BYTES) { reject_header($c, 'length') ? next : last }
        if ($h->{tt} != 0x01 && $C->{framing_transfer} ne 'trust') {
            reject_header($c, 'transfer') ? next : last;
        }
        my $known = known_action($h->{act});
        if (!$known && $C->{framing_action} ne 'trust') { reject_header($c, 'action') ? next : last }
        if ($h->{tt} == 0x01 && $known && $C->{framing_shape} ne 'trust'
            && !shape_ok($h->{act}, $h->{bt}, $h->{n}, $h->{l})) {
            malformed($c, $h->{act});
            reject_header($c, 'shape') ? next : last;
        }
        my $total = 12 + $blen + 2;
        if ($H{pre_frame} && $H{pre_frame}->($c, $h, $total)) { $c->{scanning} = 0; next }
        my $need = $H{need_bytes} ? $H{need_bytes}->($total) : $total;
        last if length($$b) < $need;
        my $take = length($$b) < $total ? length($$b) : $total;
        my $frame = substr($$b, 0, $take, '');
        $frame .= "\x00" x ($total - $take);
        $c->{scanning} = 0;
        handle_frame($c, $frame);
    }
}

# ---------------------------------------------------------------- UDP
sub udp_frame {    # the datagram's frame if it is exactly one frame with a good CRC
    my ($d) = @_;
    return $H{udp_frame}->($d) if $H{udp_frame};
    return undef if length($d) < 14;
    my $h = hdr_fields($d);
    return undef unless length($d) == 14 + $h->{n} * $h->{l};
    my $body = substr($d, 0, length($d) - 2);
    my $chk = substr($d, -2);
    my $ok = $H{udp_check_ok} ? $H{udp_check_ok}->($body, $chk) : unpack('n', $chk) == crc16_modbus($body);
    return $ok ? $d : undef;
}

sub udp_in {
    my $d = '';
    my $peer = recv($UDP, $d, 65536, 0);
    return unless defined $peer;
    my $frame = udp_frame($d);
    return unless defined $frame;
    my $h = hdr_fields($frame);
    return unless start_ok($frame) && $h->{ver} == 0x0001;
    my $c = $UDPPEER{$peer} //= { udp => 1, peer => $peer, cycle => 0, q => [] };
    handle_frame($c, $frame);
}

# ---------------------------------------------------------------- main loop
sub accept_conn {
    my $s = $LISTEN->accept or return;
    if ($H{on_accept} && !$H{on_accept}->($s)) { close $s; return }
    $s->blocking(0);
    setsockopt($s, IPPROTO_TCP, TCP_NODELAY, 1);
    my $c = { sock => $s, fd => fileno($s), buf => '', out => '', q => [], cycle => 0 };
    $CONN{ $c->{fd} } = $c;
    $SEL_R->add($s);
}

sub read_conn {
    my ($c) = @_;
    my $r = sysread($c->{sock}, my $chunk, 65536);
    if (!defined $r) {
        return if $! == EWOULDBLOCK || $! == EAGAIN || $! == EINTR;
        $r = 0;
    }
    if ($r == 0) {    # the robot closed its side
        if ($H{on_peer_close}) { return if $H{on_peer_close}->($c) }
        close_conn($c);    # answers still queued go out first (a half-closed robot reads them)
        return;
    }
    $c->{buf} .= $chunk;
    process($c);
}

sub main {
    my @argv = @_;
    if (@argv && $argv[0] eq '--list') { print "$_\n" for all_names(); return 0 }
    my $name = shift @argv;
    my $port = 0;
    GetOptionsFromArray(\@argv, 'port=i' => \$port) or die "usage: box.pl NAME --port N\n";
    die "usage: box.pl NAME --port N\n" unless defined $name;
    load_box($name) or die "unknown box $name\n";
    $SIG{PIPE} = 'IGNORE';
    $SIG{TERM} = $SIG{INT} = sub { exit 0 };
    $LISTEN = IO::Socket::INET->new(LocalAddr => '127.0.0.1', LocalPort => $port, Proto => 'tcp',
        Listen => 512, ReuseAddr => 1) or die "listen: $!\n";
    $UDP = IO::Socket::INET->new(LocalAddr => '127.0.0.1', LocalPort => 0, Proto => 'udp')
        or die "udp: $!\n";
    $LISTEN->blocking(0);
    $UDP->blocking(0);
    $SEL_R = IO::Select->new($LISTEN, $UDP);
    $SEL_W = IO::Select->new();
    $H{init}->() if $H{init};
    $| = 1;
    my $line = sprintf('listening tcp 127.0.0.1:%d udp 127.0.0.1:%d', $LISTEN->sockport, $UDP->sockport);
    $line .= ' args ' . join(' ', @{ $C->{args} }) if @{ $C->{args} };
    print "$line\n";
    while (1) {
        my $now = time;
        my $t = 1.0;
        for my $c (values %CONN) {
            next unless @{ $c->{q} };
            my $d = $c->{q}[0]{due} - $now;
            $t = $d if $d < $t;
        }
        $t = 0 if $t < 0;
        my ($r, $w) = IO::Select->select($SEL_R, $SEL_W, undef, $t);
        for my $s (@{ $r || [] }) {
            if    ($s == $LISTEN) { accept_conn() }
            elsif ($s == $UDP)    { udp_in() }
            elsif (my $c = $CONN{ fileno($s) // -1 }) { read_conn($c) }
        }
        for my $s (@{ $w || [] }) {
            my $c = $CONN{ fileno($s) // -1 } or next;
            pump($c);
        }
        for my $c (values %CONN) { pump($c) if @{ $c->{q} } }
    }
}

exit(main(@ARGV) // 0) unless caller;
1;
