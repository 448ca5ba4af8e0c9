'use strict';
// Defect box d32: the legal box legal-a with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-a',
  patch: function (B) {
  const orig = B.readHeader;
  B.readHeader = (buf) => { const h = orig(buf); h.version = buf[3]; return h; };
},
  probe: async function (t) {
  t.expect(await t.once(t.ping({ version: 0x0101 })), 0x00, 0x0000, 'version 01 01');
  t.expectNotOk(await t.once(t.ping({ version: 0x0002 }), 300), 'version 00 02');
},
};
