'use strict';
// Defect box d21: the legal box legal-b with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-b',
  patch: function (B) {
  B.indexesOk = () => true;
},
  probe: async function (t) {
  const f = t.first;
  t.expect(await t.once(t.frame({ action: 0x23, btype: 1, blocks: [t.poseBlock(f), t.poseBlock(f)] })), 0x23, 0, 'repeat');
  t.expect(await t.once(t.frame({ action: 0x23, btype: 1, blocks: [t.poseBlock(f), t.poseBlock(f + 2)] })), 0x23, 0, 'gap');
  t.expect(await t.once(t.frame({ action: 0x25, btype: 2, blocks: [t.tolBlock(9)] })), 0x25, 0, 'wrong first');
},
};
