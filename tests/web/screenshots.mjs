// Makes the studio's pictures in docs/: studio.png (an object in the 3D view, pressed by the
// simulated hand), studio-sketch.png (the pad with its contour preview), studio-viewer.png (a
// watch-only page), studio-sign-in.png (a page opened without a token). Runs against a rheod of its
// own with --device sim-spidar-g.
//
//   node tests/web/screenshots.mjs --rheod build/dev/server/daemon/rheod --web-root clients/web

import { startDaemon, parseArgs, launchBrowser, openPage, drawStrokes, sleep } from './harness.mjs';
import { readFileSync } from 'node:fs';
import { fileURLToPath } from 'node:url';

const docs = (name) => fileURLToPath(new URL(`../../docs/${name}`, import.meta.url));
const bean = JSON.parse(readFileSync(fileURLToPath(new URL('../../samples/bean.json', import.meta.url)), 'utf8'));

const args = parseArgs();
const daemon = await startDaemon(args, { device: 'sim-spidar-g' });
const browser = await launchBrowser(args);
let failed = false;
const t0 = Date.now();
const T = (m) => console.log(`${((Date.now() - t0) / 1000).toFixed(1)} s ${m}`);
try {
  const page = await openPage(browser, `${daemon.url}/`);
  // A photo behind the pad (traced by hand, as a person would), then the bean drawn with pointer events, a point in three (the pad keeps every event it gets).
  await page.locator('#bg-file').setInputFiles(fileURLToPath(new URL('../../samples/bean.photo.png', import.meta.url)));
  await page.getByRole('slider', { name: 'Background opacity', exact: true }).fill('0.3');
  await drawStrokes(page, bean.strokes.map((s) => s.filter((_, i) => i % 5 === 0 || i === s.length - 1)));
  await page.waitForFunction(() => /Contour: \d+ points/.test(document.querySelector('#pad-info').textContent), null, { timeout: 20000 });
  await page.getByLabel('Name', { exact: true }).fill('jelly bean');
  await page.getByRole('slider', { name: 'Resolution', exact: true }).fill('10');
  await sleep(300);
  T('drawn');
  await page.locator('aside.left .panel').first().screenshot({ path: docs('studio-sketch.png') });

  await page.getByRole('button', { name: 'Create', exact: true }).click();
  await page.waitForFunction(() => window.rheo.stats().objects >= 1, null, { timeout: 60000 });
  const viewer = await openPage(browser, `${daemon.url}/?view`, { width: 1200, height: 750 });
  await viewer.waitForFunction(() => window.rheo.stats().objects >= 1, null, { timeout: 20000 });
  await sleep(1500);
  // Press the simulated hand into the middle of the object.
  T('created');
  await page.getByRole('button', { name: 'Press here', exact: true }).click();
  const box = await page.getByRole('img', { name: '3D view', exact: true }).boundingBox();
  const hit = await page.evaluate(() => {
    const v = window.rheo.view;
    const o = [...v.objects.values()][0];
    const c = o.geometry.boundingSphere.center.clone().project(v.camera);
    const r = v.canvas.getBoundingClientRect();
    return [r.left + ((c.x + 1) / 2) * r.width, r.top + ((1 - c.y) / 2) * r.height];
  });
  await page.mouse.click(hit[0], hit[1]);
  await page.waitForFunction(() => window.rheo.lastFrame()?.tool?.inContact, null, { timeout: 15000 }).catch(() => {});
  await sleep(1200);
  await page.evaluate(() => (document.querySelector('aside.left').scrollTop = 0));
  await page.screenshot({ path: docs('studio.png') });
  T('pressed');

  await viewer.screenshot({ path: docs('studio-viewer.png') });
  const anon = await openPage(browser, `${daemon.url}/`, { width: 1000, height: 560, token: '' });
  await anon.waitForSelector('#sign-in', { timeout: 10000 });
  await anon.screenshot({ path: docs('studio-sign-in.png') });
  console.log('wrote docs/studio.png, docs/studio-sketch.png, docs/studio-viewer.png, docs/studio-sign-in.png');
} catch (e) {
  failed = true;
  console.error(e);
  console.error(daemon.tail());
} finally {
  await browser.close();
  await daemon.stop();
}
process.exit(failed ? 1 : 0);
