'use strict';
// Defect box d04: the legal box legal-a with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-a',
  patch: function (B) {
  const orig = B.serve;
  B.serve = (conn, hdr, blocks, frame) => {
    if ((hdr.action === 0x23 || hdr.action === 0x24) && !B.cycle(conn).cycle) return B.answer(conn, hdr, hdr.action, 0x1001);
    return orig(conn, hdr, blocks, frame);
  };
},
  probe: async function (t) {
  const s = await t.conn();
  const c = await t.conn();
  t.expect(await s.ask(t.poseReq(1, t.first)), 0x23, 0x1001, 'before CycleOn');
  t.expect(await c.ask(t.blockless(1)), 1, 0, 'CycleOn');
  t.expect(await s.ask(t.poseReq(1, t.first)), 0x23, 0, 'in cycle');
  t.expect(await c.ask(t.blockless(2)), 2, 0, 'CycleOff');
  t.expect(await s.ask(t.poseReq(1, t.first)), 0x23, 0x1001, 'after CycleOff');
  c.end(); s.end();
},
};
