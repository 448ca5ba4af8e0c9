'use strict';
// Defect box d36: the legal box legal-c with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-c',
  patch: function (B) {
  B.transferOk = () => true;
},
  probe: async function (t) {
  t.expect(await t.once(t.ping({ tt: 0x10 })), 0x00, 0x0000, 'transfer 10');
  t.expect(await t.once(t.ping({ tt: 0x02 })), 0x00, 0x0000, 'transfer 02');
},
};
