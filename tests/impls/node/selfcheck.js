#!/usr/bin/env node
// Self-check of the Node.js boxes, with its own small client (no test-suite code).
//   node selfcheck.js            every box
//   node selfcheck.js NAME ...   only these
// Starts each box, checks a legal box against a short conformance script, a defect box's
// valid request and its trigger, and kills every box it started. Every wait is bounded.
'use strict';
const net = require('net');
const dgram = require('dgram');
const path = require('path');
const fs = require('fs');
const { spawn } = require('child_process');
const { LEGAL, crc16modbus, listNames, SOAK } = require('./box.js');

const BOX = path.join(__dirname, 'box.js');
const PROCS = new Set();
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

// ---------------------------------------------------------------------------
// frames
const H = (hex) => Buffer.from(hex.replace(/[^0-9a-fA-F]/g, ''), 'hex');
const hex = (b) => (b ? b.toString('hex').toUpperCase().replace(/(..)/g, '$1 ').trim() : String(b));

function frame(o) {
  const blocks = o.blocks || [];
  const N = o.N != null ? o.N : blocks.length;
  const L = o.L != null ? o.L : blocks.length ? blocks[0].length : 0;
  const data = Buffer.concat(blocks);
  const buf = Buffer.alloc(14 + data.length);
  buf.writeUInt16BE(o.start != null ? o.start : 0xfefe, 0);
  buf.writeUInt16BE(o.version != null ? o.version : 1, 2);
  buf[4] = o.tt != null ? o.tt : 1;
  buf[5] = o.action || 0;
  buf[6] = o.btype != null ? o.btype : 0;
  buf[7] = N;
  buf.writeUInt16BE(L, 8);
  buf.writeUInt16BE(o.err || 0, 10);
  data.copy(buf, 12);
  const end = buf.length - 2;
  if (o.udp) buf.writeUInt16BE(crc16modbus(buf, 0, end), end);
  else if (o.check != null) buf.writeUInt16BE(o.check, end);
  return buf;
}
function poseBlock(idx, v = [800, -12.5, 350.25, 180, 0, 90]) {
  const b = Buffer.alloc(25);
  b[0] = idx;
  v.forEach((x, i) => b.writeFloatBE(x, 1 + 4 * i));
  return b;
}
function tolBlock(idx, v = 0.5) {
  const b = Buffer.alloc(5);
  b[0] = idx;
  b.writeFloatBE(v, 1);
  return b;
}
function intBlock(idx, v) {
  const b = Buffer.alloc(5);
  b[0] = idx;
  b.writeInt32BE(v, 1);
  return b;
}
function poseReq(n = 1, first = 0, action = 0x23, extra = {}) {
  const blocks = [];
  for (let i = 0; i < n; i++) blocks.push(poseBlock((first + i) & 0xff));
  return frame(Object.assign({ action, btype: 1, blocks }, extra));
}
function tolReq(n = 1, first = 0, v = 0.5, extra = {}) {
  const blocks = [];
  for (let i = 0; i < n; i++) blocks.push(tolBlock((first + i) & 0xff, v));
  return frame(Object.assign({ action: 0x25, btype: 2, blocks }, extra));
}
const ping = (extra = {}) => frame(Object.assign({ action: 0 }, extra));
const blockless = (action, extra = {}) => frame(Object.assign({ action }, extra));

function parseAnswer(b) {
  if (!b || !Buffer.isBuffer(b)) return null;
  return {
    start: b.readUInt16BE(0), version: b.readUInt16BE(2), tt: b[4], action: b[5], btype: b[6],
    N: b[7], L: b.readUInt16BE(8), code: b.readUInt16BE(10),
    check: b.readUInt16BE(b.length - 2), data: b.subarray(12, b.length - 2),
  };
}

// ---------------------------------------------------------------------------
// a TCP client that splits the byte stream into frames
class Client {
  constructor(port) { this.port = port; this.buf = Buffer.alloc(0); this.frames = []; this.waiters = []; this.closed = false; }
  open(ms = 2000) {
    return new Promise((resolve, reject) => {
      const s = net.connect({ port: this.port, host: '127.0.0.1' });
      s.setNoDelay(true);
      this.sock = s;
      const t = setTimeout(() => { s.destroy(); reject(new Error('connect timeout')); }, ms);
      s.on('connect', () => { clearTimeout(t); resolve(this); });
      s.on('error', (e) => { clearTimeout(t); this.closed = true; this.error = e; this._wake(); reject(e); });
      s.on('data', (d) => { this.buf = Buffer.concat([this.buf, d]); this._split(); });
      s.on('close', () => { this.closed = true; this._wake(); });
    });
  }
  _split() {
    for (;;) {
      if (this.buf.length < 12) break;
      const len = 14 + this.buf[7] * this.buf.readUInt16BE(8);
      if (this.buf.length < len) break;
      this.frames.push(this.buf.subarray(0, len));
      this.buf = this.buf.subarray(len);
    }
    this._wake();
  }
  _wake() { const w = this.waiters; this.waiters = []; w.forEach((f) => f()); }
  send(b) { this.sock.write(typeof b === 'string' ? H(b) : b); return this; }
  // next frame, or 'closed', or null after ms
  next(ms = 1500) {
    return new Promise((resolve) => {
      const t0 = Date.now();
      const check = () => {
        if (this.frames.length) return resolve(this.frames.shift());
        if (this.closed) return resolve('closed');
        const left = ms - (Date.now() - t0);
        if (left <= 0) return resolve(null);
        const wake = () => { clearTimeout(timer); check(); };
        const timer = setTimeout(() => { this.waiters = this.waiters.filter((f) => f !== wake); check(); }, left);
        this.waiters.push(wake);
      };
      check();
    });
  }
  async ask(b, ms = 1500) { this.send(b); return this.next(ms); }
  end() { try { this.sock.destroy(); } catch (e) { /* */ } }
}

// ---------------------------------------------------------------------------
function startBox(name) {
  return new Promise((resolve, reject) => {
    const p = spawn(process.execPath, [BOX, name, '--port', '0'], { stdio: ['ignore', 'pipe', 'pipe'] });
    PROCS.add(p);
    p.on('exit', () => PROCS.delete(p));
    let out = '';
    let err = '';
    const t = setTimeout(() => { p.kill('SIGKILL'); reject(new Error('box did not start: ' + err)); }, 5000);
    p.stderr.on('data', (d) => { err += d; });
    p.stdout.on('data', (d) => {
      out += d;
      const i = out.indexOf('\n');
      if (i < 0) return;
      clearTimeout(t);
      const line = out.slice(0, i);
      const m = /^listening tcp 127\.0\.0\.1:(\d+)(?: udp 127\.0\.0\.1:(\d+))?(?: args (.*))?$/.exec(line);
      if (!m) { p.kill('SIGKILL'); reject(new Error('bad first line: ' + line)); return; }
      resolve({ proc: p, line, port: +m[1], udpPort: m[2] ? +m[2] : null, args: m[3] ? m[3].split(' ') : [], stderr: () => err });
    });
    p.on('error', reject);
  });
}
function stopBox(box) {
  return new Promise((resolve) => {
    if (box.proc.exitCode != null) return resolve(box.proc.exitCode);
    const t = setTimeout(() => { box.proc.kill('SIGKILL'); }, 2000);
    box.proc.on('exit', (code) => { clearTimeout(t); resolve(code); });
    box.proc.kill('SIGTERM');
  });
}

// the helper object a probe receives
function tester(box) {
  const t = {
    box, H, hex, frame, poseBlock, tolBlock, intBlock, poseReq, tolReq, ping, blockless, parseAnswer, sleep, crc16modbus,
    first: box.args.includes('--first-index') ? +box.args[box.args.indexOf('--first-index') + 1] : 0,
    async conn() { return new Client(box.port).open(); },
    // one request on a fresh connection
    async once(b, ms = 1500) { const c = await t.conn(); const a = await c.ask(b, ms); c.end(); return a; },
    // one datagram from a fresh socket; answer or null
    udp(b, ms = 800, sock) {
      return new Promise((resolve) => {
        const s = sock || dgram.createSocket('udp4');
        let done = false;
        const fin = (v) => { if (done) return; done = true; clearTimeout(timer); s.removeListener('message', onMsg); if (!sock) s.close(); resolve(v); };
        const onMsg = (m) => fin(m);
        const timer = setTimeout(() => fin(null), ms);
        s.on('message', onMsg);
        s.send(typeof b === 'string' ? H(b) : b, box.udpPort, '127.0.0.1');
      });
    },
    expect(a, action, code, what) {
      const p = parseAnswer(a);
      if (!p) throw new Error(`${what || ''}: expected action ${action.toString(16)} code ${code.toString(16).padStart(4, '0')}, got ${hex(a)}`);
      if (p.start !== 0xfefe || p.version !== 1 || p.tt !== 0x10 || p.action !== action || p.code !== code)
        throw new Error(`${what || ''}: expected action ${action.toString(16)} code ${code.toString(16).padStart(4, '0')}, got ${hex(a)}`);
      return p;
    },
    expectExact(a, hexs, what) {
      if (!Buffer.isBuffer(a) || !a.equals(H(hexs))) throw new Error(`${what || ''}: expected ${hexs}, got ${hex(a)}`);
    },
    // an answer that is not 0000: silence, close, or non-zero error
    expectNotOk(a, what) {
      const p = parseAnswer(a);
      if (p && p.code === 0) throw new Error(`${what || ''}: answered 0000: ${hex(a)}`);
    },
    assert(c, what) { if (!c) throw new Error(what); },
    async alive(what = 'alive') { const a = await t.once(ping()); t.expect(a, 0, 0, what); },
  };
  return t;
}

// ---------------------------------------------------------------------------
// legal box: a short conformance script from PROTOCOL.md
async function legalScript(t, cfg) {
  const f = t.first;
  t.expectExact(await t.once(ping()), 'FE FE 00 01 10 00 00 00 00 00 00 00 00 00', 'A4 ping');
  t.expectExact(await t.once(poseReq(1, f)), 'FE FE 00 01 10 23 00 00 00 00 00 00 00 00', 'B1 pose');
  t.expect(await t.once(poseReq(3, f, 0x24)), 0x24, 0, 'register pose x3');
  t.expect(await t.once(poseReq(255, f)), 0x23, 0, 'pose x255');
  t.expect(await t.once(tolReq(17, f)), 0x25, 0, 'tolerance x17');
  t.expect(await t.once(ping({ check: crc16modbus(ping(), 0, 12) })), 0, 0, 'F6 crc accepted');
  // session on two connections
  const cmd = await t.conn();
  const stream = await t.conn();
  for (let i = 0; i < 5; i++) stream.send(poseReq(1, f));
  t.expect(await cmd.ask(blockless(1), 4000), 1, 0, 'S2 CycleOn');
  for (let i = 0; i < 5; i++) stream.send(poseReq(1, f));
  t.expect(await cmd.ask(poseReq(1, f)), 0x23, 0, 'pose on command connection');
  t.expect(await cmd.ask(blockless(2)), 2, 0, 'CycleOff');
  for (let i = 0; i < 10; i++) t.expect(await stream.next(1500), 0x23, 0, 'S6 stream pose ' + i);
  cmd.end(); stream.end();
  // malformed requests
  t.expect(await t.once(poseReq(2, f, 0x23, { blocks: [poseBlock(f), poseBlock(f + 2)] })), 0x23, 0x1001, 'B3 gap');
  t.expect(await t.once(poseReq(1, f ^ 1)), 0x23, 0x1001, 'B3 wrong first index');
  t.expect(await t.once(frame({ action: 0x25, btype: 1, blocks: [poseBlock(f)] })), 0x25, 0x1002, 'B5 pose blocks in 25');
  const nanPose = frame({ action: 0x23, btype: 1, blocks: [poseBlock(f, [NaN, 0, 0, 0, 0, 0])] });
  if (cfg.nan === 'accept') t.expect(await t.once(nanPose), 0x23, 0, 'B4 NaN lenient');
  else t.expect(await t.once(nanPose), 0x23, 0x1001, 'B4 NaN');
  // not requests: never 0000, and the box stays alive
  for (const [what, b] of [
    ['F2 version', ping({ version: 2 })], ['F3 transfer', ping({ tt: 0x10 })],
    ['A5 action', blockless(0x30)], ['F1 start', ping({ start: 0xfefd })],
    ['R5 oversize', H('FE FE 00 01 01 23 01 FF FF FF 00 00')],
  ]) {
    const c = await t.conn();
    c.send(b);
    t.expectNotOk(await c.next(300), what);
    c.end();
    await t.alive('R2 after ' + what);
  }
  // R6: garbage then a valid frame: answered or closed
  {
    const c = await t.conn();
    const a = await c.ask(Buffer.concat([H('00 11 22 FE 33'), ping()]), 1500);
    if (a !== 'closed') t.expect(a, 0, 0, 'R6 resync');
    c.end();
  }
  // R4: several frames in one segment; R3: one byte per segment
  {
    const c = await t.conn();
    c.send(Buffer.concat([ping(), poseReq(1, f), tolReq(1, f), ping()]));
    t.expect(await c.next(), 0, 0, 'R4 1'); t.expect(await c.next(), 0x23, 0, 'R4 2');
    t.expect(await c.next(), 0x25, 0, 'R4 3'); t.expect(await c.next(), 0, 0, 'R4 4');
    const b = poseReq(1, f);
    for (let i = 0; i < b.length; i++) { c.send(b.subarray(i, i + 1)); await sleep(1); }
    t.expect(await c.next(), 0x23, 0, 'R3 bytes');
    c.end();
  }
  // S4: a silent half frame on one connection does not delay another
  {
    const idle = await t.conn();
    idle.send(poseReq(1, f).subarray(0, 20));
    await t.alive('S4');
    idle.end();
  }
  // UDP
  t.assert(t.box.udpPort, 'udp port');
  {
    const a = await t.udp(ping({ udp: true }));
    t.expectExact(a, 'FE FE 00 01 10 00 00 00 00 00 00 00 ' + crc16modbus(H('FE FE 00 01 10 00 00 00 00 00 00 00')).toString(16).padStart(4, '0'), 'F7 udp ping');
    t.expectExact(ping({ udp: true }), 'FE FE 00 01 01 00 00 00 00 00 00 00 63 35', 'doc example crc');
    t.expect(await t.udp(poseReq(2, f, 0x23, { udp: true })), 0x23, 0, 'udp pose');
    t.assert((await t.udp(ping({ udp: true, check: 0x1234 }).fill(0x12, 12, 13))) === null, 'R7 bad crc silent');
    t.assert((await t.udp(Buffer.concat([ping({ udp: true }), ping({ udp: true })]))) === null, 'R7 two frames silent');
  }
  // extension
  if (cfg.extension) {
    const a = t.expect(await t.once(frame({ action: 0x26, btype: 3, blocks: [intBlock(f, 3)] })), 0x26, 0, 'E2');
    t.assert(a.btype === 3 && a.N === 1 && a.L === 5 && a.data[0] === f, 'E2 block ' + hex(a.data));
    const v = a.data.readInt32BE(1);
    t.assert(v === 3 || v === 409, 'E2 value ' + v);
    const r = t.expect(await t.once(blockless(0x27)), 0x27, 0, 'E3');
    t.assert(r.btype === 3 && r.N === 1 && r.L === 5, 'E3 block');
    t.assert([1, 2, 10, 20, 202, 400, 409].includes(r.data.readInt32BE(1)), 'E3 code');
  } else {
    t.expectNotOk(await t.once(blockless(0x27), 300), 'E absent');
    await t.alive('after 27');
  }
  // R5: 200 idle connections and a hanging oversize header do not stop the box
  {
    const idle = [];
    for (let i = 0; i < 200; i++) idle.push(await t.conn());
    idle[0].send(H('FE FE 00 01 01 23 01 FF FF FF 00 00'));
    idle[1].send(poseReq(1, f).subarray(0, 30));
    await t.alive('R5 idle connections');
    idle.forEach((c) => c.end());
  }
  // T2/S6: 2 s of poses at 50 Hz, answers read as they come; latency does not grow
  {
    const c = await t.conn();
    const sent = [];
    const lat = [];
    const reader = (async () => {
      for (let i = 0; i < 100; i++) {
        const a = await c.next(3000);
        t.expect(a, 0x23, 0, 'T2 pose ' + i);
        lat.push(Date.now() - sent[i]);
      }
    })();
    for (let i = 0; i < 100; i++) { sent.push(Date.now()); c.send(poseReq(1, f)); await sleep(20); }
    await reader;
    c.end();
    const head = Math.max(...lat.slice(0, 20));
    const tail = Math.max(...lat.slice(80));
    t.assert(tail < head + 60 && tail < (cfg.latency + 100), `T2 latency ${head} -> ${tail} ms`);
  }
  // S5: connect/disconnect cycles
  for (let i = 0; i < 30; i++) { const c = await t.conn(); await c.ask(ping()); c.end(); }
  await t.alive('S5');
}

// a defect box, or a soak box: its valid request first
async function validRequest(t) {
  t.expect(await t.once(ping()), 0x00, 0x0000, 'valid request (ping)');
}

async function soakScript(t, name) {
  await validRequest(t);
  if (name === 'soak-d') {
    for (let i = 0; i < 299; i++) { const c = await t.conn(); await c.ask(ping()); c.end(); await sleep(1); }
    await sleep(100);
    const c = await t.conn();
    const a = await c.ask(ping(), 500);
    c.end();
    t.assert(a === null, 'soak-d silent after 300 sessions: ' + hex(a));
  }
}

// ---------------------------------------------------------------------------
function defectModule(name) {
  for (const dir of ['tuning', 'heldout']) {
    const f = path.join(__dirname, dir, name + '.js');
    if (fs.existsSync(f)) return require(f);
  }
  return null;
}

async function checkOne(name) {
  const t0 = Date.now();
  let box;
  try {
    box = await startBox(name);
    const t = tester(box);
    if (LEGAL[name]) {
      const cfg = Object.assign({}, require('./box.js').DEFAULTS, LEGAL[name]);
      await legalScript(t, cfg);
    } else if (SOAK.includes(name)) {
      await soakScript(t, name);
    } else {
      const mod = defectModule(name);
      await validRequest(t);
      await mod.probe(t);
    }
    const rc = await stopBox(box);
    if (rc !== 0) throw new Error('exit code ' + rc);
    if (box.stderr()) throw new Error('stderr: ' + box.stderr());
    return { name, ok: true, ms: Date.now() - t0 };
  } catch (e) {
    if (box) await stopBox(box);
    return { name, ok: false, ms: Date.now() - t0, err: e.message };
  }
}

async function main() {
  const only = process.argv.slice(2);
  const names = only.length ? only : listNames();
  const results = [];
  let next = 0;
  const T0 = Date.now();
  const worker = async () => {
    while (next < names.length) {
      const name = names[next++];
      const r = await checkOne(name);
      results.push(r);
      console.log(`${r.ok ? 'PASS' : 'FAIL'} ${r.name} (${r.ms} ms)${r.ok ? '' : ': ' + r.err}`);
    }
  };
  await Promise.all([worker(), worker(), worker(), worker()]);
  const bad = results.filter((r) => !r.ok);
  console.log(`${results.length - bad.length}/${results.length} boxes pass in ${((Date.now() - T0) / 1000).toFixed(1)} s`);
  process.exit(bad.length ? 1 : 0);
}

module.exports = { frame, poseBlock, tolBlock, poseReq, tolReq, ping, H, hex };
if (require.main === module) {
  const hard = setTimeout(() => {
    console.log('selfcheck: over the 2-minute bound');
    for (const p of PROCS) p.kill('SIGKILL');
    process.exit(1);
  }, 115000);
  hard.unref();
  main();
}
