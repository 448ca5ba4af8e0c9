'use strict';
// Defect box d20: the legal box legal-a with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-a',
  patch: function (B) {
  const orig = B.onOversize;
  B.onOversize = (conn, hdr) => { B.server.close(); return orig(conn, hdr); };
},
  probe: async function (t) {
  const c = await t.conn();
  c.send(t.H('FE FE 00 01 01 23 01 FF FF FF 00 00'));
  await t.sleep(200);
  let refused = false;
  try { const d = await t.conn(); d.end(); } catch (e) { refused = true; }
  t.assert(refused, 'new connection accepted');
  t.expect(await c.ask(t.ping()), 0, 0, 'open connection still served');
  c.end();
},
};
