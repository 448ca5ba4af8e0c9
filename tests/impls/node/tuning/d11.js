'use strict';
// Defect box d11: the legal box legal-c with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-c',
  patch: function (B) {
  const orig = B.serve;
  B.serve = (conn, hdr, blocks, frame) => { orig(conn, hdr, blocks, frame); if (hdr.action === 0x02 && !conn.udp) B.closeConn(conn); };
},
  probe: async function (t) {
  const c = await t.conn();
  t.expect(await c.ask(t.blockless(1)), 1, 0, 'CycleOn');
  t.expect(await c.ask(t.blockless(2)), 2, 0, 'CycleOff');
  t.assert((await c.next(1000)) === 'closed', 'not closed');
},
};
