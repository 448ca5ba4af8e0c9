'use strict';
// Defect box d16: the legal box legal-f with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-f',
  patch: function (B) {
  let closed = 0;
  const origClosed = B.onClosed;
  B.onClosed = (conn) => { closed++; origClosed(conn); };
  const orig = B.accept;
  B.accept = (sock) => { if (closed >= 50) { sock.destroy(); return; } orig(sock); };
},
  probe: async function (t) {
  let failedAt = 0;
  for (let i = 1; i <= 60 && !failedAt; i++) {
    let a = null;
    try { const c = await t.conn(); a = await c.ask(t.ping(), 800); c.end(); } catch (e) { a = 'error'; }
    if (!Buffer.isBuffer(a)) failedAt = i;
    await t.sleep(5);
  }
  t.assert(failedAt >= 45 && failedAt <= 55, 'failed at connection ' + failedAt);
},
};
