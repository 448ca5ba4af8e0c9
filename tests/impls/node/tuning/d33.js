'use strict';
// Defect box d33: the legal box legal-e with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-e',
  patch: function (B) {
  const orig = B.encode;
  B.encode = (conn, a) => { const b = orig(conn, a); const end = b.length - 2; b.writeUInt16BE(B.frameCrc(b, end), end); return b; };
},
  probe: async function (t) {
  const a = await t.once(t.ping());
  t.expectExact(a, 'FE FE 00 01 10 00 00 00 00 00 00 00 ' + t.crc16modbus(t.H('FE FE 00 01 10 00 00 00 00 00 00 00')).toString(16).padStart(4, '0'), 'crc in TCP answer');
},
};
