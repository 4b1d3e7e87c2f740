// Move a parameter slider (k_v) of a scene object: the daemon runs the new value, read back
// through the API (ListParameters over the page's own connection), and the panel shows it.

import { run, openPage, assert, pageCall, sleep, createThroughApi } from './harness.mjs';
import { readFileSync } from 'node:fs';
import { fileURLToPath } from 'node:url';

const sample = readFileSync(fileURLToPath(new URL('../../samples/bean.json', import.meta.url)), 'utf8');

run('web.params', async ({ daemon, browser }) => {
  const page = await openPage(browser, `${daemon.url}/`);
  // The object is made through the API (the create test covers the pad); the panel follows it.
  const progress = await createThroughApi(page, 'bean', sample, 0.014);
  const inst = progress[progress.length - 1].sceneObject.instanceId;
  assert(inst > 0, 'added to the scene');
  await page.waitForFunction((id) => document.querySelector('#param-instance').value === String(id), inst, { timeout: 15000 });

  const slider = page.getByRole('slider', { name: 'k_v', exact: true });
  await slider.waitFor();
  const before = (await pageCall(page, 'rheo.v1.SceneService/ListParameters', { instanceId: inst })).parameters.find(
    (p) => p.name === 'k_v',
  ).value;
  // Keyboard on the slider, as a person would: each arrow press is one step on its scale.
  await slider.focus();
  for (let i = 0; i < 40; i++) await page.keyboard.press('ArrowRight');
  const shown = Number(await page.getByRole('spinbutton', { name: 'k_v', exact: true }).inputValue());
  assert(shown > before, `the number follows the slider (${before} -> ${shown})`);

  let after = before;
  for (let i = 0; i < 50 && after !== shown; i++) {
    await sleep(100);
    after = (await pageCall(page, 'rheo.v1.SceneService/ListParameters', { instanceId: inst })).parameters.find(
      (p) => p.name === 'k_v',
    ).value;
  }
  assert(Math.abs(after - shown) <= 1e-9 * Math.max(1, shown), `the daemon runs k_v = ${shown}, it has ${after}`);
  const server = await page.locator('.param', { has: page.getByRole('slider', { name: 'k_v', exact: true }) }).locator('output').textContent();
  assert(Math.abs(Number(server) - after) <= 1e-3 * after, `the panel shows the server's value (${server})`);

  // A typed value out of range: refused with the daemon's words, the value that runs is kept.
  const num = page.getByRole('spinbutton', { name: 'k_v', exact: true });
  await num.fill('-5');
  await num.press('Enter');
  await page.locator('#app-alert').filter({ hasText: 'k_v' }).waitFor({ timeout: 10000 });
  const kept = (await pageCall(page, 'rheo.v1.SceneService/ListParameters', { instanceId: inst })).parameters.find((p) => p.name === 'k_v').value;
  assert(kept === after, 'a refused value changes nothing');
  assert(page.errors.length === 0, `page errors: ${page.errors.join('; ')}`);
});
