'use strict';
// Defect box d12: the legal box legal-f with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-f',
  patch: function (B) {
  const orig = B.handleFrame;
  B.handleFrame = (conn, hdr, frame) => { conn.count = (conn.count || 0) + 1; if (conn.count > 300) return; orig(conn, hdr, frame); };
},
  probe: async function (t) {
  const c = await t.conn();
  const batch = [];
  for (let i = 0; i < 301; i++) batch.push(t.ping());
  c.send(Buffer.concat(batch));
  for (let i = 0; i < 300; i++) t.expect(await c.next(2000), 0, 0, 'ping ' + i);
  t.assert((await c.next(600)) === null, '301st answered');
  c.end();
  await t.alive('new connection');
},
};
