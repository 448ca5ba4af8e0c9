#!/usr/bin/env node
// Independent AI Box implementations of the iSight socket protocol, written from
// docs/PROTOCOL.md alone (see README.md). Node.js 20, standard library only.
//
//   node box.js NAME --port 0     serve box NAME on 127.0.0.1 (TCP, and UDP on its own port)
//   node box.js --list            print every box name
'use strict';
const net = require('net');
const dgram = require('dgram');
const fs = require('fs');
const path = require('path');

const EMPTY = Buffer.alloc(0);
const MAX_BLOCK_BYTES = 255 * 25; // the largest legal frame: 255 pose blocks

// ---------------------------------------------------------------------------
// CRC-16/MODBUS (poly 0x8005 reflected = 0xA001, init 0xFFFF, xorout 0)
function crc16modbus(buf, start = 0, end = buf.length) {
  let crc = 0xffff;
  for (let i = start; i < end; i++) {
    crc ^= buf[i];
    for (let b = 0; b < 8; b++) crc = crc & 1 ? (crc >>> 1) ^ 0xa001 : crc >>> 1;
  }
  return crc & 0xffff;
}

// ---------------------------------------------------------------------------
// The legal boxes: every value is a choice PROTOCOL.md / LEGAL-CHOICES.md allows.
const DEFAULTS = {
  firstIndex: 0,          // B3: 0 | 1 (1 needs --first-index 1)
  garbage: 'scan',        // R6: bytes that are not FE FE: scan (b) | close (c)
  version: 1,             // R6: bad version: resume+k (1..12) | 'close'
  length: 1,              // R6/R5: oversize header: resume+k | 'close'
  transfer: 'trust',      // R6: transfer type not 01: 'trust' (a) | k | 'close'
  action: 'trust',        // R6: unknown action: 'trust' | k | 'close'
  shape: 'trust',         // R6: block type/count/length not fitting the action: 'trust' | k
  notRequest: 'silent',   // A5: silent | error | close
  refusalAction: 'echo',  // A5: echo | 00
  refusalCode: 0xffff,    // A5: any non-zero code
  blockless: 'error',     // A3: malformed 00/01/02: error | silent | close
  reqErrorField: 'accept',// a request whose error field is not 0000: accept | reject
  tcpCheck: 'zero-or-crc',// F6: ignore | zero-or-crc
  cycleScope: 'box',      // S3: box | connection
  cycleOnTwice: 0,        // S3: 0000 | 0001
  cycleOffIdle: 0,        // S3: 0000 | 0002
  extension: true,        // E: present | absent
  progIdx: 'index',       // E2: index | 409
  result: 1,              // E3: 1 2 10 20 202 409
  nan: 'reject',          // B4: reject | accept (needs --checking lenient)
  latency: 0,             // ms before an answer goes out (below time_out)
  cycleOnLatency: null,   // ms for CycleOn (null: latency)
  writer: 'whole',        // whole | bytes | pieces
  nagle: false,           // Nagle's algorithm on the accepted sockets
  args: [],               // profile flags the tester needs
};

const LEGAL = {
  'legal-a': {},
  'legal-b': {
    firstIndex: 1, garbage: 'close', version: 'close', length: 'close', transfer: 'close',
    action: 'close', notRequest: 'close', blockless: 'close', cycleScope: 'connection',
    cycleOnTwice: 1, cycleOffIdle: 2, extension: false, latency: 10, nagle: true,
    writer: 'pieces', args: ['--first-index', '1'],
  },
  'legal-c': {
    version: 12, length: 12, transfer: 12, action: 12, shape: 12, notRequest: 'error',
    refusalAction: '00', refusalCode: 0xffff, tcpCheck: 'ignore', reqErrorField: 'reject',
    progIdx: '409', result: 202, latency: 60, writer: 'bytes', nagle: true,
  },
  'legal-d': {
    version: 5, length: 5, action: 5, shape: 1, notRequest: 'error', refusalCode: 0x0001,
    cycleScope: 'connection', nan: 'accept', result: 2, latency: 2,
    args: ['--checking', 'lenient'],
  },
  'legal-e': {
    firstIndex: 1, version: 'close', length: 5, transfer: 1, action: 12, blockless: 'silent',
    cycleOffIdle: 2, cycleOnLatency: 1500, latency: 20, extension: false, nagle: true,
    args: ['--first-index', '1'],
  },
  'legal-f': {
    version: 12, length: 'close', shape: 1, notRequest: 'error', refusalCode: 0x1001,
    cycleOnTwice: 1, result: 10, writer: 'pieces', reqErrorField: 'reject',
  },
};

const SOAK = ['soak-a', 'soak-b', 'soak-c', 'soak-d'];

function defectFile(name) {
  for (const dir of ['tuning', 'heldout']) {
    const f = path.join(__dirname, dir, name + '.js');
    if (fs.existsSync(f)) return f;
  }
  return null;
}

function listNames() {
  const names = Object.keys(LEGAL);
  for (const dir of ['tuning', 'heldout']) {
    const d = path.join(__dirname, dir);
    if (!fs.existsSync(d)) continue;
    for (const f of fs.readdirSync(d).sort()) if (/^d\d+\.js$/.test(f)) names.push(f.slice(0, -3));
  }
  names.sort((a, b) => (a < b ? -1 : a > b ? 1 : 0));
  return names.concat(SOAK);
}

const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

// ---------------------------------------------------------------------------
// The box. Every step is a method of B so that a defect can replace exactly one.
function makeBox(cfg) {
  const B = { cfg, state: { cycle: false }, crc: crc16modbus, conns: new Set() };

  // ---- header and blocks -------------------------------------------------
  B.readHeader = (buf) => ({
    start: buf.readUInt16BE(0), version: buf.readUInt16BE(2), tt: buf[4], action: buf[5],
    btype: buf[6], N: buf[7], L: buf.readUInt16BE(8), err: buf.readUInt16BE(10),
  });
  B.frameLen = (hdr) => 12 + hdr.N * hdr.L + 2;
  B.versionOk = (hdr) => hdr.version === 0x0001;
  B.oversize = (hdr) => hdr.N * hdr.L > MAX_BLOCK_BYTES;
  B.transferOk = (hdr) => hdr.tt === 0x01;
  B.actionKnown = (hdr) => [0x00, 0x01, 0x02, 0x23, 0x24, 0x25].includes(hdr.action) ||
    (cfg.extension && (hdr.action === 0x26 || hdr.action === 0x27));
  B.shapeOk = (hdr) => {
    switch (hdr.action) {
      case 0x00: case 0x01: case 0x02: case 0x27:
        return hdr.btype === 0 && hdr.N === 0 && hdr.L === 0;
      case 0x23: case 0x24: return hdr.btype === 1 && hdr.N >= 1 && hdr.L === 25;
      case 0x25: return hdr.btype === 2 && hdr.N >= 1 && hdr.L === 5;
      case 0x26: return hdr.btype === 3 && hdr.N === 1 && hdr.L === 5;
      default: return false;
    }
  };
  B.readFloat = (buf, off) => buf.readFloatBE(off);
  B.readInt = (buf, off) => buf.readInt32BE(off);
  B.blocks = (hdr, frame) => {
    const out = [];
    const nv = hdr.btype === 1 ? 6 : 1;
    for (let i = 0; i < hdr.N; i++) {
      const off = 12 + i * hdr.L;
      const b = { index: frame[off], values: [] };
      for (let k = 0; k < nv; k++) {
        b.values.push(hdr.btype === 3 ? B.readInt(frame, off + 1 + 4 * k) : B.readFloat(frame, off + 1 + 4 * k));
      }
      out.push(b);
    }
    return out;
  };
  B.indexesOk = (hdr, blocks) => blocks.every((b, i) => b.index === ((cfg.firstIndex + i) & 0xff));
  B.valuesOk = (hdr, blocks) => {
    if (cfg.nan === 'accept' || hdr.btype === 3) return true;
    return blocks.every((b) => b.values.every((v) => Number.isFinite(v)));
  };
  B.blocksOk = (hdr, blocks) => B.indexesOk(hdr, blocks) && B.valuesOk(hdr, blocks);
  B.tcpCheckOk = (conn, hdr, frame) => {
    if (cfg.tcpCheck === 'ignore') return true;
    const end = frame.length - 2;
    const c = frame.readUInt16BE(end);
    return c === 0 || c === B.frameCrc(frame, end);
  };
  B.frameCrc = (frame, end) => B.crc(frame, 0, end);

  // ---- answers -----------------------------------------------------------
  B.writeCode = (buf, code) => buf.writeUInt16BE(code & 0xffff, 10);
  B.encode = (conn, a) => {
    const N = a.N || 0, L = a.L || 0;
    const buf = Buffer.alloc(14 + N * L);
    buf.writeUInt16BE(0xfefe, 0);
    buf.writeUInt16BE(0x0001, 2);
    buf[4] = 0x10;
    buf[5] = a.action;
    buf[6] = a.btype || 0;
    buf[7] = N;
    buf.writeUInt16BE(L, 8);
    B.writeCode(buf, a.code);
    if (a.data) a.data.copy(buf, 12);
    const end = buf.length - 2;
    buf.writeUInt16BE(conn.udp ? B.frameCrc(buf, end) : 0, end);
    return buf;
  };
  B.latencyFor = (conn, hdr) =>
    (hdr && hdr.action === 0x01 && cfg.cycleOnLatency != null ? cfg.cycleOnLatency : cfg.latency);
  B.answer = (conn, hdr, action, code, extra) => {
    const a = Object.assign({ action, code }, extra || {});
    B.send(conn, B.encode(conn, a), B.latencyFor(conn, hdr));
  };
  B.intBlock = (value) => {
    const d = Buffer.alloc(5);
    d[0] = cfg.firstIndex;
    d.writeInt32BE(value, 1);
    return { btype: 3, N: 1, L: 5, data: d };
  };

  // ---- output queue: answers leave in request order, each at its due time --
  B.send = (conn, buf, delay) => {
    conn.q.push({ buf, due: Date.now() + (delay || 0) });
    if (!conn.pumping) B.pump(conn);
  };
  B.closeConn = (conn) => {
    // close after the answers already queued have gone out
    conn.closing = true;
    conn.q.push({ close: true, due: 0 });
    if (!conn.pumping) B.pump(conn);
  };
  B.pump = async (conn) => {
    conn.pumping = true;
    try {
      while (conn.q.length) {
        const it = conn.q[0];
        const wait = it.due - Date.now();
        if (wait > 0) await sleep(wait);
        conn.q.shift();
        if (conn.closed) continue;
        if (it.close) { B.hangUp(conn); continue; }
        await B.write(conn, it.buf);
      }
    } finally {
      conn.pumping = false;
    }
  };
  B.write = async (conn, buf) => {
    if (conn.udp) { conn.sendUdp(buf); return; }
    const s = conn.sock;
    if (cfg.writer === 'bytes') {
      for (let i = 0; i < buf.length; i++) s.write(buf.subarray(i, i + 1));
    } else if (cfg.writer === 'pieces') {
      s.write(buf.subarray(0, 12));
      await sleep(5);
      if (!conn.closed) s.write(buf.subarray(12));
    } else {
      s.write(buf);
    }
  };
  B.hangUp = (conn) => {
    if (conn.udp || conn.closed) return;
    conn.closed = true;
    conn.sock.end();
    setTimeout(() => conn.sock.destroy(), 200).unref();
  };

  // ---- reactions -----------------------------------------------------------
  B.notRequest = (conn, hdr) => {
    if (cfg.notRequest === 'close') { if (conn.udp) return; B.closeConn(conn); return; }
    if (cfg.notRequest === 'error') {
      B.answer(conn, hdr, cfg.refusalAction === 'echo' ? hdr.action : 0x00, cfg.refusalCode);
    }
  };
  B.malformed = (conn, hdr) => {
    switch (hdr.action) {
      case 0x23: case 0x24: B.answer(conn, hdr, hdr.action, 0x1001); return;
      case 0x25: B.answer(conn, hdr, hdr.action, 0x1002); return;
      case 0x26: case 0x27: return; // no code named: silence
      default:
        if (cfg.blockless === 'close') { if (!conn.udp) B.closeConn(conn); return; }
        if (cfg.blockless === 'silent') return;
        B.answer(conn, hdr, hdr.action, hdr.action === 0x01 ? 0x0001 : hdr.action === 0x02 ? 0x0002 : 0xffff);
    }
  };
  B.cycle = (conn) => (cfg.cycleScope === 'box' ? B.state : conn.state);

  // ---- a whole frame that passed the header checks -------------------------
  B.handleFrame = (conn, hdr, frame) => {
    if (!conn.udp && !B.tcpCheckOk(conn, hdr, frame)) return B.malformed(conn, hdr);
    if (hdr.err !== 0 && cfg.reqErrorField === 'reject') return B.malformed(conn, hdr);
    const blocks = B.blocks(hdr, frame);
    if (!B.blocksOk(hdr, blocks)) return B.malformed(conn, hdr);
    B.serve(conn, hdr, blocks, frame);
  };
  B.serve = (conn, hdr, blocks, frame) => {
    const st = B.cycle(conn);
    switch (hdr.action) {
      case 0x00: B.answer(conn, hdr, 0x00, 0x0000); break;
      case 0x01: {
        let code = 0;
        if (st.cycle) code = cfg.cycleOnTwice ? 0x0001 : 0;
        st.cycle = true;
        B.answer(conn, hdr, 0x01, code);
        break;
      }
      case 0x02: {
        const code = !st.cycle && cfg.cycleOffIdle ? 0x0002 : 0;
        st.cycle = false;
        B.answer(conn, hdr, 0x02, code);
        break;
      }
      case 0x23: case 0x24: conn.lastPose = blocks; B.answer(conn, hdr, hdr.action, 0x0000); break;
      case 0x25: conn.tolerance = blocks; B.answer(conn, hdr, hdr.action, 0x0000); break;
      case 0x26: {
        const v = cfg.progIdx === '409' ? 409 : blocks[0].values[0];
        B.answer(conn, hdr, 0x26, 0x0000, B.intBlock(v));
        break;
      }
      case 0x27: B.answer(conn, hdr, 0x27, 0x0000, B.intBlock(cfg.result)); break;
    }
  };

  // ---- TCP framing ----------------------------------------------------------
  B.feed = (conn, chunk) => {
    conn.buf = conn.buf.length ? Buffer.concat([conn.buf, chunk]) : chunk;
    return B.drain(conn);
  };
  B.drain = (conn, max = Infinity) => {
    let n = 0;
    while (!conn.closing && !conn.closed && n < max) {
      const r = B.step(conn);
      if (r === 'wait') break;
      if (r === 'frame') n++;
    }
    return n;
  };
  B.drop = (conn, k) => { conn.buf = conn.buf.subarray(Math.min(k, conn.buf.length)); };
  B.reject = (conn, hdr, policy, react) => {
    if (policy === 'close') { B.closeConn(conn); return 'stop'; }
    if (react) B.notRequest(conn, hdr);
    B.drop(conn, policy);
    return 'skip';
  };
  B.scan = (conn) => {
    const buf = conn.buf;
    if (cfg.garbage === 'close') { conn.buf = EMPTY; B.closeConn(conn); return 'stop'; }
    for (let i = 1; i < buf.length - 1; i++) {
      if (buf[i] === 0xfe && buf[i + 1] === 0xfe) { conn.buf = buf.subarray(i); return 'skip'; }
    }
    conn.buf = buf[buf.length - 1] === 0xfe ? buf.subarray(buf.length - 1) : EMPTY;
    return 'skip';
  };
  B.onOversize = (conn, hdr) => B.reject(conn, hdr, cfg.length, false);
  B.step = (conn) => {
    const buf = conn.buf;
    if (buf.length === 0) return 'wait';
    if (buf[0] !== 0xfe || (buf.length >= 2 && buf[1] !== 0xfe)) return B.scan(conn);
    if (buf.length < 12) return 'wait';
    const hdr = B.readHeader(buf);
    if (!B.versionOk(hdr)) return B.reject(conn, hdr, cfg.version, true);
    if (B.oversize(hdr)) return B.onOversize(conn, hdr);
    const len = B.frameLen(hdr);
    if (!B.transferOk(hdr)) {
      if (cfg.transfer !== 'trust') return B.reject(conn, hdr, cfg.transfer, true);
      if (buf.length < len) return 'wait';
      B.drop(conn, len);
      B.notRequest(conn, hdr);
      return 'frame';
    }
    if (!B.actionKnown(hdr)) {
      if (cfg.action !== 'trust') return B.reject(conn, hdr, cfg.action, true);
      if (buf.length < len) return 'wait';
      B.drop(conn, len);
      B.notRequest(conn, hdr);
      return 'frame';
    }
    if (!B.shapeOk(hdr)) {
      if (cfg.shape !== 'trust') { B.malformed(conn, hdr); B.drop(conn, cfg.shape); return 'skip'; }
      if (buf.length < len) return 'wait';
      B.drop(conn, len);
      B.malformed(conn, hdr);
      return 'frame';
    }
    if (buf.length < len) return 'wait';
    const frame = buf.subarray(0, len);
    B.drop(conn, len);
    B.handleFrame(conn, hdr, frame);
    return 'frame';
  };

  // ---- UDP: one datagram, one frame, CRC-16 ----------------------------------
  B.udpLengthOk = (msg, hdr) => msg.length === B.frameLen(hdr);
  B.udpCrcOk = (msg) => {
    const end = msg.length - 2;
    return msg.readUInt16BE(end) === B.frameCrc(msg, end);
  };
  B.udpHandle = (ctx, msg) => {
    if (msg.length < 14) return;
    const hdr = B.readHeader(msg);
    if (!B.udpLengthOk(msg, hdr)) return;
    const frame = msg.subarray(0, B.frameLen(hdr));
    if (!B.udpCrcOk(frame)) return;
    if (hdr.start !== 0xfefe) return;
    if (!B.versionOk(hdr) || !B.transferOk(hdr) || !B.actionKnown(hdr)) return B.notRequest(ctx, hdr);
    if (!B.shapeOk(hdr)) return B.malformed(ctx, hdr);
    B.handleFrame(ctx, hdr, frame);
  };

  // ---- connections -------------------------------------------------------
  B.newConn = (sock) => ({
    sock, buf: EMPTY, q: [], pumping: false, closing: false, closed: false,
    state: { cycle: false }, n: 0,
  });
  B.accept = (sock) => {
    sock.setNoDelay(!cfg.nagle);
    const conn = B.newConn(sock);
    B.conns.add(conn);
    sock.on('data', (chunk) => { if (!conn.closing && !conn.closed) B.feed(conn, chunk); });
    sock.on('error', () => {});
    sock.on('end', () => { if (!conn.closed && !conn.closing) B.closeConn(conn); });
    sock.on('close', () => { conn.closed = true; B.conns.delete(conn); B.onClosed(conn); });
    B.onAccepted(conn);
  };
  B.onAccepted = () => {};
  B.onClosed = () => {};

  B.udpCtx = new Map();
  B.udpMessage = (msg, rinfo) => {
    const key = rinfo.address + ':' + rinfo.port;
    let ctx = B.udpCtx.get(key);
    if (!ctx) {
      if (B.udpCtx.size > 1024) B.udpCtx.clear(); // bounded (R5)
      ctx = {
        udp: true, q: [], pumping: false, closing: false, closed: false,
        state: { cycle: false }, n: 0, rinfo,
        sendUdp: (buf) => B.udpSock.send(buf, rinfo.port, rinfo.address),
      };
      B.udpCtx.set(key, ctx);
    }
    B.udpHandle(ctx, msg);
  };
  return B;
}

// ---------------------------------------------------------------------------
// Endurance defects (not split; see soak/CATALOGUE.json)
function soakPatch(name, B) {
  if (name === 'soak-a') {
    // keeps a 100 KiB buffer for every closed connection
    const kept = [];
    B.onClosed = () => { kept.push(Buffer.alloc(100 * 1024, 1)); };
  } else if (name === 'soak-b') {
    // answer latency grows by 1 ms per 200 requests served, box-wide, for ever
    let served = 0;
    const orig = B.latencyFor;
    B.latencyFor = (conn, hdr) => orig(conn, hdr) + Math.floor(served++ / 200);
  } else if (name === 'soak-c') {
    // a connection whose peer went silent (no FIN, no RST) is never freed; past 64 such
    // stale connections every new one is refused
    const origAccept = B.accept;
    B.accept = (sock) => {
      const now = Date.now();
      let stale = 0;
      for (const c of B.conns) if (now - c.last >= 5000) stale++;
      if (stale >= 64) { sock.destroy(); return; }
      origAccept(sock);
    };
    const origNew = B.newConn;
    B.newConn = (sock) => { const c = origNew(sock); c.last = Date.now(); return c; };
    const origFeed = B.feed;
    B.feed = (conn, chunk) => { conn.last = Date.now(); return origFeed(conn, chunk); };
  } else if (name === 'soak-d') {
    // stops serving after 300 sessions (connections that sent a request and closed)
    let sessions = 0;
    const origFrame = B.handleFrame;
    B.handleFrame = (conn, hdr, frame) => {
      conn.used = true;
      if (sessions >= 300) return;
      origFrame(conn, hdr, frame);
    };
    B.onClosed = (conn) => { if (conn.used) sessions++; };
  }
}

// ---------------------------------------------------------------------------
function buildBox(name) {
  if (LEGAL[name]) return { B: makeBox(Object.assign({}, DEFAULTS, LEGAL[name])), name };
  if (SOAK.includes(name)) {
    const B = makeBox(Object.assign({}, DEFAULTS));
    soakPatch(name, B);
    return { B, name };
  }
  const f = defectFile(name);
  if (!f) return null;
  const mod = require(f);
  const B = makeBox(Object.assign({}, DEFAULTS, LEGAL[mod.base]));
  mod.patch(B);
  return { B, name };
}

function main(argv) {
  if (argv.includes('--list')) {
    process.stdout.write(listNames().join('\n') + '\n');
    return;
  }
  const name = argv[0];
  let port = 0;
  const pi = argv.indexOf('--port');
  if (pi >= 0) port = Number(argv[pi + 1]);
  const built = name && buildBox(name);
  if (!built) {
    process.stderr.write(`unknown box: ${name} (node box.js --list)\n`);
    process.exit(2);
  }
  const { B } = built;
  const server = net.createServer({ noDelay: !B.cfg.nagle }, (sock) => B.accept(sock));
  B.server = server;
  server.maxConnections = 100000;
  const udp = dgram.createSocket('udp4');
  B.udpSock = udp;
  udp.on('message', (msg, rinfo) => { try { B.udpMessage(msg, rinfo); } catch (e) { /* dropped */ } });
  udp.on('error', () => {});
  server.on('error', (e) => { process.stderr.write(`fatal: ${e.message}\n`); process.exit(1); });
  server.listen(port, '127.0.0.1', () => {
    udp.bind(0, '127.0.0.1', () => {
      let line = `listening tcp 127.0.0.1:${server.address().port} udp 127.0.0.1:${udp.address().port}`;
      if (B.cfg.args.length) line += ' args ' + B.cfg.args.join(' ');
      process.stdout.write(line + '\n');
    });
  });
  const stop = () => process.exit(0);
  process.on('SIGTERM', stop);
  process.on('SIGINT', stop);
  process.on('uncaughtException', (e) => {
    // a box keeps serving; a bug in one connection's handling must not kill it
    if (!B.reportedFatal) { B.reportedFatal = true; }
  });
}

module.exports = { makeBox, LEGAL, DEFAULTS, crc16modbus, listNames, SOAK };

if (require.main === module) main(process.argv.slice(2));
