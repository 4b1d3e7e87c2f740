// Two pages, the studio and a watch-only /?view, watch the same simulation: both receive frames
// whose stamp ticks advance, over the same span of ticks, and both see the same object.

import { run, openPage, assert, sleep, createThroughApi } from './harness.mjs';
import { readFileSync } from 'node:fs';
import { fileURLToPath } from 'node:url';

const sample = readFileSync(fileURLToPath(new URL('../../samples/ellipse.json', import.meta.url)), 'utf8');

/** Starts recording the stamp ticks of every frame the page's view applies. */
function recordTicks(page) {
  return page.evaluate(() => {
    window.__ticks = [];
    const view = window.rheo.view;
    const apply = view.applyFrame.bind(view);
    view.applyFrame = (f) => {
      window.__ticks.push(Number(f.stamp?.tick || 0));
      apply(f);
    };
  });
}

run('web.viewers', async ({ daemon, browser }) => {
  const studio = await openPage(browser, `${daemon.url}/`);
  const viewer = await openPage(browser, `${daemon.url}/?view`);
  await createThroughApi(studio, 'ellipse', sample, 0.016);
  await recordTicks(studio);
  await recordTicks(viewer);
  await sleep(2000);
  const a = await studio.evaluate(() => window.__ticks);
  const b = await viewer.evaluate(() => window.__ticks);
  for (const [name, t] of [['studio', a], ['viewer', b]]) {
    assert(t.length >= 10, `${name} got ${t.length} frames in 2 s`);
    for (let i = 1; i < t.length; i++) assert(t[i] > t[i - 1], `${name}: ticks advance (${t[i - 1]} then ${t[i]})`);
  }
  const lo = Math.max(a[0], b[0]);
  const hi = Math.min(a[a.length - 1], b[b.length - 1]);
  assert(hi - lo > 500, `the two pages watched the same ticks (overlap ${lo}..${hi})`);
  await viewer.waitForFunction(() => window.rheo.stats().objects === 1, null, { timeout: 10000 });
  const vs = await viewer.evaluate(() => window.rheo.stats());
  assert(vs.connected && vs.fps > 0, `viewer stats ${JSON.stringify(vs)}`);
  // The loop's publish to this page's receipt, as the page measures it.
  const l = vs.latencyMs;
  assert(l.count > 10 && l.p50 >= 0 && l.p99 < 5000, `frame latency ${JSON.stringify(l)}`);
  console.log(`browser frame latency: p50 ${l.p50} ms, p99 ${l.p99} ms over ${l.count} frames`);
  // The status line counts both pages' frame streams.
  await viewer.locator('#st-viewers').filter({ hasText: /viewers [2-9]/ }).waitFor({ timeout: 10000 });
  assert(studio.errors.length === 0 && viewer.errors.length === 0, `page errors: ${[...studio.errors, ...viewer.errors].join('; ')}`);
});
