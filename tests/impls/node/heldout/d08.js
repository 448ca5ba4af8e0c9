'use strict';
// Defect box d08: the legal box legal-c with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-c',
  patch: function (B) {
  B.udpCrcOk = () => true;
},
  probe: async function (t) {
  t.expect(await t.udp(t.ping()), 0, 0, 'bad crc ping');
  t.expect(await t.udp(t.poseReq(1, t.first, 0x23, { check: 0x1234 })), 0x23, 0, 'bad crc pose');
},
};
