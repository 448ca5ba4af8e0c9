'use strict';
// Defect box d03: the legal box legal-d with one mechanism broken (see CATALOGUE.json).
// Loaded by ../box.js; probe() is used by ../selfcheck.js only.
module.exports = {
  base: 'legal-d',
  patch: function (B) {
  const orig = B.serve;
  B.serve = (conn, hdr, blocks, frame) => {
    if (hdr.action === 0x01 && !B.stalled) {
      B.stalled = true;
      const until = Date.now() + 6000;
      while (Date.now() < until) { /* busy initialisation */ }
    }
    return orig(conn, hdr, blocks, frame);
  };
},
  probe: async function (t) {
  const a = await t.conn();
  const b = await t.conn();
  a.send(t.blockless(1));
  await t.sleep(200);
  const t0 = Date.now();
  t.expect(await b.ask(t.ping(), 8000), 0, 0, 'ping during stall');
  t.assert(Date.now() - t0 > 4000, 'ping not delayed: ' + (Date.now() - t0));
  t.expect(await a.next(3000), 1, 0, 'CycleOn');
  a.end(); b.end();
},
};
