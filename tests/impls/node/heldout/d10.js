'use strict';
// Defect box d10: the legal box legal-a with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-a',
  patch: function (B) {
  const orig = B.serve;
  B.serve = (conn, hdr, blocks, frame) => {
    if ([0x23, 0x24, 0x25].includes(hdr.action)) {
      return B.answer(conn, hdr, hdr.action, 0, { btype: hdr.btype, N: hdr.N, L: hdr.L, data: Buffer.from(frame.subarray(12, frame.length - 2)) });
    }
    return orig(conn, hdr, blocks, frame);
  };
},
  probe: async function (t) {
  const a = t.expect(await t.once(t.poseReq(1, t.first)), 0x23, 0, 'pose');
  t.assert(a.btype === 1 && a.N === 1 && a.L === 25, 'blocks echoed: ' + t.hex(a.data));
},
};
