'use strict';
// Defect box d30: the legal box legal-d with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-d',
  patch: function (B) {
  const orig = B.shapeOk;
  B.shapeOk = (hdr) => {
    if ([0x23, 0x24, 0x25].includes(hdr.action) && ((hdr.N << 24) >> 24) < 1) return false;
    return orig(hdr);
  };
},
  probe: async function (t) {
  t.expect(await t.once(t.poseReq(127, t.first)), 0x23, 0, '127 blocks');
  t.expect(await t.once(t.poseReq(128, t.first)), 0x23, 0x1001, '128 blocks');
  t.expect(await t.once(t.tolReq(200, t.first)), 0x25, 0x1002, '200 tolerance blocks');
},
};
