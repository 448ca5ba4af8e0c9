'use strict';
// Defect box d18: the legal box legal-d with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-d',
  patch: function (B) {
  const orig = B.answer;
  B.answer = (conn, hdr, action, code, extra) => orig(conn, hdr, action === 0x24 ? 0x23 : action, code, extra);
},
  probe: async function (t) {
  t.expectExact(await t.once(t.poseReq(1, t.first, 0x24)), 'FE FE 00 01 10 23 00 00 00 00 00 00 00 00', 'register pose');
},
};
