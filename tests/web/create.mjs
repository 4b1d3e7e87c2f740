// Draw a closed shape on the "Sketch pad", see the contour preview, press Create: the object is
// stored, added to the scene, appears in the "3D view", and the view's pixels change as it falls.

import { run, openPage, drawStrokes, blob, assert, pageCall, sleep } from './harness.mjs';

run('web.create', async ({ daemon, browser }) => {
  const page = await openPage(browser, `${daemon.url}/`);
  const pad = page.getByRole('img', { name: 'Sketch pad', exact: true });
  await pad.waitFor();

  // Two overlapping strokes making one closed outline.
  const pts = blob();
  await drawStrokes(page, [pts.slice(0, 45), pts.slice(40)]);
  await page.waitForFunction(() => /Contour: \d+ points/.test(document.querySelector('#pad-info').textContent), null, {
    timeout: 15000,
  });
  assert((await page.locator('#pad-alert').textContent()) === '', 'no refusal for a closed outline');

  // Paused, the new object hangs where it was placed until Resume lets it fall.
  await page.getByRole('button', { name: 'Pause', exact: true }).click();
  await page.getByLabel('Name', { exact: true }).fill('test blob');
  await page.getByRole('slider', { name: 'Resolution', exact: true }).fill('14');
  await page.getByRole('button', { name: 'Create', exact: true }).click();
  await page.waitForFunction(() => window.rheo.stats().objects >= 1, null, { timeout: 60000 });

  const stored = await pageCall(page, 'rheo.v1.ObjectService/ListObjects', {});
  assert(stored.objects.length === 1 && stored.objects[0].name === 'test blob', 'one object stored, named');
  const scene = await pageCall(page, 'rheo.v1.SceneService/GetScene', {});
  assert(scene.objects.length === 1 && scene.objects[0].objectId === stored.objects[0].id, 'the object is in the scene');

  // It falls onto the floor: two screenshots of the 3D view differ.
  const view = page.getByRole('img', { name: '3D view', exact: true });
  await sleep(500);
  const a = await view.screenshot();
  await page.getByRole('button', { name: 'Resume', exact: true }).click();
  await sleep(1000);
  const b = await view.screenshot();
  assert(!a.equals(b), 'the 3D view changes while the object falls');

  const s = await page.evaluate(() => window.rheo.stats());
  assert(s.connected && s.frames > 0 && s.objects === 1, `stats ${JSON.stringify(s)}`);
  assert((await page.locator('#library .lib-item').count()) === 1, 'the library lists it');
  // Its thumbnail is the SVG export; its OBJ downloads.
  await page.waitForFunction(() => document.querySelector('#library .thumb')?.naturalWidth > 0, null, { timeout: 15000 });
  const [download] = await Promise.all([
    page.waitForEvent('download', { timeout: 15000 }),
    page.getByRole('link', { name: 'Download test blob as OBJ', exact: true }).click(),
  ]);
  assert(download.suggestedFilename() === 'test_blob.obj', `file name ${download.suggestedFilename()}`);
  const obj = await (await import('node:fs/promises')).readFile(await download.path(), 'utf8');
  assert(/^v\s/m.test(obj) && /^f\s/m.test(obj), 'the OBJ has vertices and faces');
  assert(page.errors.length === 0, `page errors: ${page.errors.join('; ')}`);
});
