'use strict';
// Defect box d06: the legal box legal-a with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-a',
  patch: function (B) {
  B.onAccepted = (conn) => { conn.sock.setTimeout(3000, () => B.hangUp(conn)); };
},
  probe: async function (t) {
  const c = await t.conn();
  t.expect(await c.ask(t.ping()), 0, 0, 'ping');
  const t0 = Date.now();
  t.assert((await c.next(4500)) === 'closed', 'not closed');
  t.assert(Date.now() - t0 > 2000, 'closed too early');
},
};
