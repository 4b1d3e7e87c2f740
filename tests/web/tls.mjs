// The studio over TLS in a real browser: rheod with a certificate made here serves the page over
// https and its API over wss (the same certificate as gRPC), on a non-loopback address without
// --insecure; the page signs in, builds an object and watches it move.

import { spawnSync } from 'node:child_process';
import { mkdtempSync, rmSync, writeFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { run, openPage, assert, createThroughApi } from './harness.mjs';

const dir = mkdtempSync(join(tmpdir(), 'rheo-web-tls-'));
const openssl = (...a) => {
  const r = spawnSync('/usr/bin/openssl', a, { encoding: 'utf8' });
  if (r.status !== 0) throw new Error(`openssl ${a[0]}: ${r.stderr}`);
};
const at = (f) => join(dir, f);
openssl('req', '-x509', '-newkey', 'ec', '-pkeyopt', 'ec_paramgen_curve:prime256v1', '-nodes',
  '-keyout', at('ca.key'), '-out', at('ca.pem'), '-days', '2', '-subj', '/CN=rheo web test CA');
openssl('req', '-newkey', 'ec', '-pkeyopt', 'ec_paramgen_curve:prime256v1', '-nodes',
  '-keyout', at('server.key'), '-out', at('server.csr'), '-subj', '/CN=localhost');
writeFileSync(at('server.ext'), 'subjectAltName=DNS:localhost,IP:127.0.0.1\n');
openssl('x509', '-req', '-in', at('server.csr'), '-CA', at('ca.pem'), '-CAkey', at('ca.key'),
  '-CAcreateserial', '-out', at('server.pem'), '-days', '2', '-extfile', at('server.ext'));

const square = JSON.stringify({
  width: 400,
  height: 400,
  strokes: [[[100, 100], [300, 100], [300, 300], [100, 300], [100, 100]]],
});

run(
  'web.tls',
  async ({ daemon, browser }) => {
    assert(/^https:\/\/0\.0\.0\.0:\d+$/.test(daemon.url), `the studio is at https: ${daemon.url}`);
    assert(!/--insecure/.test(daemon.log), 'no --insecure warning under TLS');
    const url = daemon.url.replace('0.0.0.0', '127.0.0.1');
    const page = await openPage(browser, `${url}/`, { ignoreHTTPSErrors: true });
    const where = await page.evaluate(() => ({ page: location.protocol, api: window.rheo.rpc.url }));
    assert(where.page === 'https:', `the page came over https: ${JSON.stringify(where)}`);
    assert(/^wss:\/\//.test(where.api), `the API goes over wss: ${JSON.stringify(where)}`);
    await page.waitForFunction(() => window.rheo.identity && window.rheo.identity.name === 'admin', null, {
      timeout: 10000,
    });
    const made = await createThroughApi(page, 'square', square, 0.01);
    const object = made.find((p) => p.object)?.object;
    assert(object && object.id, 'an object built over wss');
    await page.waitForFunction(() => window.rheo.stats().frames > 10, null, { timeout: 15000 });
    if (process.env.RHEO_SCREENSHOTS) await page.screenshot({ path: join(process.env.RHEO_SCREENSHOTS, 'tls.png') });
    assert(page.errors.length === 0, `no page errors: ${page.errors.join('; ')}`);
    // Plain http to the TLS port gets no studio.
    const plain = await fetch(`${url.replace('https:', 'http:')}/`).then(
      (r) => r.status,
      () => 'refused',
    );
    assert(plain === 'refused', `plaintext http to the TLS port: ${plain}`);
    rmSync(dir, { recursive: true, force: true });
  },
  {
    extra: ['--http', '0.0.0.0:0', '--tls-cert', at('server.pem'), '--tls-key', at('server.key')],
  },
);
