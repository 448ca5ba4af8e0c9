'use strict';
// Defect box d24: the legal box legal-f with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-f',
  patch: function (B) {
  const orig = B.readHeader;
  B.readHeader = (buf) => { const h = orig(buf); h.L = buf[9]; return h; };
},
  probe: async function (t) {
  const blk = Buffer.concat([t.poseBlock(t.first), Buffer.alloc(256)]);
  const c = await t.conn();
  t.expect(await c.ask(t.frame({ action: 0x23, btype: 1, L: 0x0119, blocks: [blk] })), 0x23, 0, 'L=0x0119');
  c.end();
},
};
