// A fine mesh takes a while: Create shows its progress, Cancel stops it (CancelJob and
// the stream's cancel), the pad says so, and nothing is stored.

import { run, openPage, drawStrokes, blob, assert, pageCall, sleep } from './harness.mjs';

run('web.cancel', async ({ daemon, browser }) => {
  const page = await openPage(browser, `${daemon.url}/`);
  await drawStrokes(page, [blob(256, 256, 200, 160, 48)]);
  await page.waitForFunction(() => /Contour: \d+ points/.test(document.querySelector('#pad-info').textContent), null, { timeout: 15000 });
  await page.getByRole('slider', { name: 'Resolution', exact: true }).fill('3');
  await page.getByRole('slider', { name: 'Thickness', exact: true }).fill('2');
  await page.getByRole('button', { name: 'Create', exact: true }).click();
  // Cancel at once, while the job runs (the stream is cancelled even before a job id arrived).
  await page.locator('#progress').waitFor({ state: 'visible' });
  await page.getByRole('button', { name: 'Cancel', exact: true }).click();
  const alert = page.locator('#pad-alert');
  await alert.filter({ hasText: /Cancelled|CANCELLED/ }).waitFor({ timeout: 20000 });
  await sleep(300);
  const stored = await pageCall(page, 'rheo.v1.ObjectService/ListObjects', {});
  assert((stored.objects || []).length === 0, 'nothing stored');
  assert(!(await page.getByRole('button', { name: 'Create', exact: true }).isDisabled()), 'Create is available again');
});
