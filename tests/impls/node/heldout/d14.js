'use strict';
// Defect box d14: the legal box legal-d with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-d',
  patch: function (B) {
  const orig = B.shapeOk;
  B.shapeOk = (hdr) => {
    if ((hdr.action === 0x23 || hdr.action === 0x24) && hdr.btype === 1 && hdr.N >= 1 && hdr.L >= 25) return true;
    return orig(hdr);
  };
},
  probe: async function (t) {
  const f = t.first;
  const blk = Buffer.concat([t.poseBlock(f), Buffer.alloc(4)]);
  t.expect(await t.once(t.frame({ action: 0x23, btype: 1, blocks: [blk] })), 0x23, 0, 'L=29');
  t.expect(await t.once(t.frame({ action: 0x25, btype: 2, L: 6, blocks: [Buffer.concat([t.tolBlock(f), Buffer.alloc(1)])] })), 0x25, 0x1002, 'tolerance L=6 still refused');
},
};
