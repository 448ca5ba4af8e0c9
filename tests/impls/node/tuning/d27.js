'use strict';
// Defect box d27: the legal box legal-c with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-c',
  patch: function (B) {
  const orig = B.serve;
  B.serve = (conn, hdr, blocks, frame) => { if (hdr.action === 0x27) return; orig(conn, hdr, blocks, frame); };
},
  probe: async function (t) {
  const c = await t.conn();
  t.expect(await c.ask(t.H('FE FE 00 01 01 26 03 01 00 05 00 00 00 00000003 00 00')), 0x26, 0, 'ProgIdx');
  t.assert((await c.ask(t.blockless(0x27), 1500)) === null, 'result answered');
  c.end();
},
};
