'use strict';
// Defect box d28: the legal box legal-a with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-a',
  patch: function (B) {
  const orig = B.blocksOk;
  B.blocksOk = (hdr, blocks) => {
    if (hdr.btype === 1 && blocks.some((b) => b.values.some((v) => Math.abs(v) > 10000))) return false;
    return orig(hdr, blocks);
  };
},
  probe: async function (t) {
  t.expect(await t.once(t.frame({ action: 0x23, btype: 1, blocks: [t.poseBlock(t.first, [9999, 0, 0, 0, 0, 0])] })), 0x23, 0, '9999');
  t.expect(await t.once(t.frame({ action: 0x23, btype: 1, blocks: [t.poseBlock(t.first, [20000, 0, 0, 0, 0, 0])] })), 0x23, 0x1001, '20000');
  t.expect(await t.once(t.frame({ action: 0x24, btype: 1, blocks: [t.poseBlock(t.first, [0, 0, -12000, 0, 0, 0])] })), 0x24, 0x1001, '-12000');
},
};
