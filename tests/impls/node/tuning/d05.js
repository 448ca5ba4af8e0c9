'use strict';
// Defect box d05: the legal box legal-d with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-d',
  patch: function (B) {
  B.udpLengthOk = (msg, hdr) => msg.length >= B.frameLen(hdr);
},
  probe: async function (t) {
  t.expect(await t.udp(Buffer.concat([t.ping({ udp: true }), t.ping({ udp: true })])), 0, 0, 'two frames');
  t.expect(await t.udp(Buffer.concat([t.ping({ udp: true }), t.H('00 11 22')])), 0, 0, 'trailing junk');
},
};
