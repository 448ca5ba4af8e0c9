'use strict';
// Defect box d31: the legal box legal-b with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-b',
  patch: function (B) {
  B.crc = (buf, start = 0, end = buf.length) => {
    let crc = 0x0000;
    for (let i = start; i < end; i++) { crc ^= buf[i]; for (let b = 0; b < 8; b++) crc = crc & 1 ? (crc >>> 1) ^ 0xa001 : crc >>> 1; }
    return crc & 0xffff;
  };
},
  probe: async function (t) {
  t.assert((await t.udp(t.ping({ udp: true }))) === null, 'MODBUS datagram answered');
  const arc = (buf) => { let crc = 0; for (const x of buf) { crc ^= x; for (let b = 0; b < 8; b++) crc = crc & 1 ? (crc >>> 1) ^ 0xa001 : crc >>> 1; } return crc; };
  const p = t.ping();
  p.writeUInt16BE(arc(p.subarray(0, 12)), 12);
  const a = await t.udp(p);
  t.assert(a && a.readUInt16BE(12) === arc(a.subarray(0, 12)), 'ARC answer: ' + t.hex(a));
},
};
