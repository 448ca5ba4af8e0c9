'use strict';
// Defect box d02: the legal box legal-f with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-f',
  patch: function (B) {
  const orig = B.feed;
  B.feed = (conn, chunk) => {
    if (conn.buf.length === 0 && chunk.length < 12) return 0;
    return orig(conn, chunk);
  };
},
  probe: async function (t) {
  const c = await t.conn();
  const p = t.ping();
  c.send(p.subarray(0, 5));
  await t.sleep(50);
  c.send(p.subarray(5));
  t.assert((await c.next(500)) === null, 'split header answered');
  t.expect(await c.ask(t.ping()), 0, 0, 'whole');
  c.end();
},
};
