// An open outline (a "C" whose ends stay far apart): ExtractContour's refusal is shown in words
// in the pad's role="alert" element, Create is refused the same way, and nothing is stored;
// Undo and Clear empty the pad and the refusal goes away.

import { run, openPage, drawStrokes, assert, pageCall, sleep } from './harness.mjs';

run('web.refusal', async ({ daemon, browser }) => {
  const page = await openPage(browser, `${daemon.url}/`);
  const arc = [];
  for (let i = 0; i <= 50; i++) {
    const t = 0.35 + (i / 50) * (2 * Math.PI - 0.7) * 0.62;
    arc.push([256 + 140 * Math.cos(t), 256 + 140 * Math.sin(t)]);
  }
  await drawStrokes(page, [arc]);
  const alert = page.locator('#pad-alert[role="alert"]');
  await alert.filter({ hasText: /\S/ }).waitFor({ timeout: 15000 });
  const words = await alert.textContent();
  assert(/INVALID_ARGUMENT/.test(words), `the refusal names its code: ${words}`);
  assert((await page.locator('#pad-info').textContent()) === '', 'no contour shown');

  await page.getByRole('button', { name: 'Create', exact: true }).click();
  await page.waitForFunction(() => !document.querySelector('#create').disabled, null, { timeout: 30000 });
  const after = await alert.textContent();
  assert(/INVALID_ARGUMENT/.test(after) && /Change the sketch/.test(after), `Create refused, with what to change: ${after}`);
  await sleep(300);
  const stored = await pageCall(page, 'rheo.v1.ObjectService/ListObjects', {});
  assert((stored.objects || []).length === 0, 'nothing stored');
  const scene = await pageCall(page, 'rheo.v1.SceneService/GetScene', {});
  assert((scene.objects || []).length === 0, 'nothing in the scene');
  console.log(`refusal shown: ${after.split('\n')[0]}`);

  // Undo takes the stroke back: the pad is empty and the refusal goes away.
  await page.getByRole('button', { name: 'Undo', exact: true }).click();
  await alert.filter({ hasText: /^$/ }).waitFor({ state: 'attached', timeout: 10000 });
  assert(await page.evaluate(() => document.querySelector('#pad-alert').textContent === ''), 'no alert after Undo');
  // Clear empties a pad of two strokes.
  await drawStrokes(page, [arc.slice(0, 20), arc.slice(25)]);
  await alert.filter({ hasText: /\S/ }).waitFor({ timeout: 15000 });
  await page.getByRole('button', { name: 'Clear', exact: true }).click();
  await page.waitForFunction(() => document.querySelector('#pad-alert').textContent === '', null, { timeout: 10000 });
});
