'use strict';
// Defect box d13: the legal box legal-a with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-a',
  patch: function (B) {
  const orig = B.latencyFor;
  B.latencyFor = (conn, hdr) => { conn.served = (conn.served || 0) + 1; return orig(conn, hdr) + Math.max(0, conn.served - 100); };
},
  probe: async function (t) {
  const c = await t.conn();
  let first = 0;
  let last = 0;
  for (let i = 1; i <= 160; i++) {
    const t0 = Date.now();
    t.expect(await c.ask(t.ping(), 2000), 0, 0, 'ping ' + i);
    if (i === 1) first = Date.now() - t0;
    last = Date.now() - t0;
  }
  c.end();
  t.assert(first < 30 && last >= 45, `latency ${first} ms -> ${last} ms`);
},
};
