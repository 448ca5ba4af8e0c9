'use strict';
// Defect box d29: the legal box legal-c with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-c',
  patch: function (B) {
  const orig = B.feed;
  B.feed = (conn, chunk) => {
    const n = orig(conn, chunk);
    const buf = conn.buf;
    if (!conn.closing && buf.length >= 12 && buf[0] === 0xfe && buf[1] === 0xfe) {
      const hdr = B.readHeader(buf);
      if (B.versionOk(hdr) && B.transferOk(hdr) && B.actionKnown(hdr) && !B.oversize(hdr) && buf.length < B.frameLen(hdr)) {
        B.malformed(conn, hdr);
        conn.buf = Buffer.alloc(0);
      }
    }
    return n;
  };
},
  probe: async function (t) {
  const c = await t.conn();
  const p = t.poseReq(1, t.first);
  c.send(p.subarray(0, 20));
  await t.sleep(50);
  c.send(p.subarray(20));
  t.expect(await c.next(), 0x23, 0x1001, 'split pose');
  t.expect(await c.ask(p), 0x23, 0, 'whole pose');
  c.end();
},
};
