// The daemon goes away under a watching page: the page shows "Connection lost — reconnecting…",
// and when a daemon is back on the same address it reconnects by itself, hides the banner and
// watches frames again.

import { run, startDaemon, openPage, assert, sleep } from './harness.mjs';

run('web.reconnect', async ({ daemon, browser, args }) => {
  const port = Number(new URL(daemon.url).port);
  const page = await openPage(browser, `${daemon.url}/?view`);
  await page.waitForFunction(() => window.rheo.stats().frames > 3, null, { timeout: 15000 });
  await daemon.kill('SIGTERM');
  const banner = page.locator('#banner');
  await banner.waitFor({ state: 'visible', timeout: 10000 });
  assert((await banner.textContent()).includes('Connection lost — reconnecting…'), 'the banner says so');
  assert(!(await page.evaluate(() => window.rheo.stats().connected)), 'stats say disconnected');

  // A daemon back on the same http port (and data dir); the run() teardown stops it.
  const again = await startDaemon(args, { httpPort: port, dataDir: daemon.dataDir });
  daemon.proc = again.proc;
  daemon.exited = null;
  again.proc.once('exit', (c, s) => (daemon.exited = c ?? s));
  daemon.log += again.log;
  await page.waitForFunction(() => window.rheo.stats().connected, null, { timeout: 20000 });
  const f0 = await page.evaluate(() => window.rheo.stats().frames);
  await page.waitForFunction((n) => window.rheo.stats().frames > n + 5, f0, { timeout: 15000 });
  await banner.waitFor({ state: 'hidden', timeout: 5000 });
  await sleep(100);
});
