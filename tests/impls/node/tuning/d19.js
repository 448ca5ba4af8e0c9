'use strict';
// Defect box d19: the legal box legal-a with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-a',
  patch: function (B) {
  B.feed = (conn, chunk) => {
    conn.buf = conn.buf.length ? Buffer.concat([conn.buf, chunk]) : chunk;
    const n = B.drain(conn, 1);
    if (n >= 1) conn.buf = Buffer.alloc(0);
    return n;
  };
},
  probe: async function (t) {
  const c = await t.conn();
  c.send(Buffer.concat([t.ping(), t.poseReq(1, t.first), t.ping()]));
  t.expect(await c.next(), 0, 0, 'first');
  t.assert((await c.next(500)) === null, 'second answered');
  t.expect(await c.ask(t.ping()), 0, 0, 'alone');
  c.end();
},
};
