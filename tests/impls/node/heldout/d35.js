'use strict';
// Defect box d35: the legal box legal-a with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-a',
  patch: function (B) {
  B.frameCrc = (frame, end) => B.crc(frame, 0, Math.min(12, end));
},
  probe: async function (t) {
  t.expect(await t.udp(t.ping({ udp: true })), 0, 0, 'udp ping');
  t.assert((await t.udp(t.poseReq(1, t.first, 0x23, { udp: true }))) === null, 'full-crc pose answered');
  const p = t.poseReq(1, t.first);
  p.writeUInt16BE(t.crc16modbus(p, 0, 12), p.length - 2);
  t.expect(await t.udp(p), 0x23, 0, 'header-crc pose');
},
};
