'use strict';
// Defect box d07: the legal box legal-a with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-a',
  patch: function (B) {
  const orig = B.latencyFor;
  B.latencyFor = (conn, hdr) => (hdr && hdr.action === 0x01 ? 5500 : orig(conn, hdr));
},
  probe: async function (t) {
  const a = await t.conn();
  const b = await t.conn();
  const t0 = Date.now();
  a.send(t.blockless(1));
  t.expect(await b.ask(t.ping(), 1000), 0, 0, 'ping meanwhile');
  t.expect(await a.next(8000), 1, 0, 'CycleOn');
  t.assert(Date.now() - t0 > 5000, 'CycleOn in ' + (Date.now() - t0));
  t.expect(await a.ask(t.blockless(2)), 2, 0, 'CycleOff');
  a.end(); b.end();
},
};
