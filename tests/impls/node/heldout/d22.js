'use strict';
// Defect box d22: the legal box legal-d with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-d',
  patch: function (B) {
  B.feed = (conn, chunk) => {
    conn.buf = conn.buf.length ? Buffer.concat([conn.buf, chunk]) : chunk;
    const n = B.drain(conn);
    if (n > 0 && conn.buf.length) conn.buf = Buffer.alloc(0);
    return n;
  };
},
  probe: async function (t) {
  const c = await t.conn();
  const p = t.ping();
  c.send(Buffer.concat([t.ping(), p.subarray(0, 5)]));
  await t.sleep(50);
  c.send(p.subarray(5));
  t.expect(await c.next(), 0, 0, 'first');
  t.assert((await c.next(500)) === null, 'second answered');
  c.end();
},
};
