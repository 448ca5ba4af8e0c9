'use strict';
// Defect box d09: the legal box legal-a with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-a',
  patch: function (B) {
  B.readFloat = (buf, off) => buf.readFloatLE(off);
},
  probe: async function (t) {
  const b = t.poseBlock(t.first, [0, 0, 0, 0, 0, 0]);
  t.H('0000807F').copy(b, 1);
  t.expect(await t.once(t.frame({ action: 0x23, btype: 1, blocks: [b] })), 0x23, 0x1001, 'finite denormal');
  t.expect(await t.once(t.frame({ action: 0x23, btype: 1, blocks: [t.poseBlock(t.first, [NaN, 0, 0, 0, 0, 0])] })), 0x23, 0, 'NaN');
},
};
