'use strict';
// Defect box d23: the legal box legal-d with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-d',
  patch: function (B) {
  const orig = B.serve;
  B.serve = (conn, hdr, blocks, frame) => {
    if ((hdr.action === 0x23 || hdr.action === 0x24) && conn.holds) return B.answer(conn, hdr, hdr.action, 0x1001);
    if (hdr.action === 0x01) conn.holds = true;
    if (hdr.action === 0x02) conn.holds = false;
    return orig(conn, hdr, blocks, frame);
  };
},
  probe: async function (t) {
  const c = await t.conn();
  const s = await t.conn();
  t.expect(await c.ask(t.poseReq(1, t.first)), 0x23, 0, 'before');
  t.expect(await c.ask(t.blockless(1)), 1, 0, 'CycleOn');
  t.expect(await s.ask(t.poseReq(1, t.first)), 0x23, 0, 'stream');
  t.expect(await c.ask(t.poseReq(1, t.first)), 0x23, 0x1001, 'command pose');
  t.expect(await c.ask(t.blockless(2)), 2, 0, 'CycleOff');
  c.end(); s.end();
},
};
