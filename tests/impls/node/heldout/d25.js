'use strict';
// Defect box d25: the legal box legal-f with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-f',
  patch: function (B) {
  const orig = B.latencyFor;
  B.latencyFor = (conn, hdr) => orig(conn, hdr) + (hdr && [0x23, 0x24, 0x25].includes(hdr.action) ? 60 * hdr.N : 0);
},
  probe: async function (t) {
  const c = await t.conn();
  let t0 = Date.now();
  t.expect(await c.ask(t.poseReq(1, t.first)), 0x23, 0, '1 block');
  t.assert(Date.now() - t0 < 1000, 'one block slow');
  t0 = Date.now();
  t.expect(await c.ask(t.poseReq(100, t.first), 8000), 0x23, 0, '100 blocks');
  t.assert(Date.now() - t0 > 5000, '100 blocks in ' + (Date.now() - t0) + ' ms');
  c.end();
},
};
