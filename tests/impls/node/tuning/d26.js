'use strict';
// Defect box d26: the legal box legal-e with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-e',
  patch: function (B) {
  const orig = B.blocksOk;
  B.blocksOk = (hdr, blocks) => ((hdr.action === 0x23 || hdr.action === 0x24) && hdr.N >= 16 ? false : orig(hdr, blocks));
},
  probe: async function (t) {
  t.expect(await t.once(t.poseReq(15, t.first)), 0x23, 0, '15 blocks');
  t.expect(await t.once(t.poseReq(16, t.first)), 0x23, 0x1001, '16 blocks');
  t.expect(await t.once(t.poseReq(40, t.first, 0x24)), 0x24, 0x1001, '40 register blocks');
},
};
