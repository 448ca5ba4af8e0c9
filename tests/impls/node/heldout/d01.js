'use strict';
// Defect box d01: the legal box legal-a with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-a',
  patch: function (B) {
  const orig = B.answer;
  B.answer = (conn, hdr, action, code, extra) => orig(conn, hdr, action, code, action === 0x26 && extra ? Object.assign({}, extra, { btype: 2 }) : extra);
},
  probe: async function (t) {
  t.expectExact(await t.once(t.H('FE FE 00 01 01 26 03 01 00 05 00 00 00 00000003 00 00')), 'FE FE 00 01 10 26 02 01 00 05 00 00 00 00000003 00 00', 'ProgIdx');
  t.expect(await t.once(t.blockless(0x27)), 0x27, 0, 'result');
},
};
