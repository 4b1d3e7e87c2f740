// A picture of a drawing as the sketch itself (a photographed sheet of paper): the pad shows it
// at its own size, the daemon's contour preview is drawn over it, and Create makes an object.

import { run, openPage, assert, pageCall } from './harness.mjs';
import { fileURLToPath } from 'node:url';

run('web.picture', async ({ daemon, browser }) => {
  const page = await openPage(browser, `${daemon.url}/`);
  await page.locator('#picture-file').setInputFiles(fileURLToPath(new URL('../../samples/heart.photo.png', import.meta.url)));
  await page.waitForFunction(() => /Contour: \d+ points/.test(document.querySelector('#pad-info').textContent), null, { timeout: 20000 });
  const size = await page.getByRole('img', { name: 'Sketch pad', exact: true }).evaluate((c) => [c.width, c.height]);
  assert(size[0] === 512 && size[1] === 512, `the pad takes the picture's size (${size})`);
  await page.getByLabel('Name', { exact: true }).fill('heart photo');
  await page.getByRole('slider', { name: 'Resolution', exact: true }).fill('15');
  await page.getByRole('button', { name: 'Create', exact: true }).click();
  await page.waitForFunction(() => window.rheo.stats().objects >= 1, null, { timeout: 60000 });
  const stored = await pageCall(page, 'rheo.v1.ObjectService/ListObjects', {});
  assert(stored.objects.length === 1 && stored.objects[0].name === 'heart photo', 'stored from the picture');
  assert(page.errors.length === 0, `page errors: ${page.errors.join('; ')}`);
});
