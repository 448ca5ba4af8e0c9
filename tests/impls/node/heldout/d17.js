'use strict';
// Defect box d17: the legal box legal-e with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-e',
  patch: function (B) {
  B.versionOk = () => true;
},
  probe: async function (t) {
  t.expect(await t.once(t.ping({ version: 2 })), 0x00, 0x0000, 'version 00 02');
  t.expect(await t.once(t.ping({ version: 0x0100 })), 0x00, 0x0000, 'version 01 00');
},
};
