'use strict';
// Defect box d34: the legal box legal-b with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-b',
  patch: function (B) {
  B.writeCode = (buf, code) => buf.writeUInt16LE(code & 0xffff, 10);
},
  probe: async function (t) {
  t.expectExact(await t.once(t.H('FE FE 00 01 01 23 01 01 00 05 00 00 00 3F000000 00 00')), 'FE FE 00 01 10 23 00 00 00 00 01 10 00 00', 'malformed pose');
},
};
