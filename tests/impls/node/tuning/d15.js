'use strict';
// Defect box d15: the legal box legal-c with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-c',
  patch: function (B) {
  const orig = B.blocksOk;
  B.blocksOk = (hdr, blocks) => (hdr.btype === 2 && blocks.some((b) => b.values[0] > 10) ? false : orig(hdr, blocks));
},
  probe: async function (t) {
  t.expect(await t.once(t.tolReq(1, t.first, 9.5)), 0x25, 0, '9.5');
  t.expect(await t.once(t.tolReq(1, t.first, 12.5)), 0x25, 0x1002, '12.5');
},
};
