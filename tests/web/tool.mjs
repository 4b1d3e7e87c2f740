// --device network: "Drag tool" takes the control lease and moves the tool with the mouse
// through ToolStream; frames show the tool where it was dragged, and stopping releases the lease.

import { run, openPage, assert, pageCall, sleep, createThroughApi } from './harness.mjs';
import { readFileSync } from 'node:fs';
import { fileURLToPath } from 'node:url';

const sample = readFileSync(fileURLToPath(new URL('../../samples/ellipse.json', import.meta.url)), 'utf8');

run(
  'web.tool',
  async ({ daemon, browser }) => {
    const page = await openPage(browser, `${daemon.url}/`);
    await createThroughApi(page, 'ellipse', sample, 0.016);
    await page.waitForFunction(() => window.rheo.stats().objects === 1, null, { timeout: 20000 });
    const drag = page.getByRole('button', { name: 'Drag tool', exact: true });
    await drag.click();
    await page.waitForFunction(() => window.rheo.lastFrame()?.tool?.leaseHolder, null, { timeout: 10000 });
    const status = await pageCall(page, 'rheo.v1.DeviceService/GetDeviceStatus', {});
    assert(status.leaseHolder !== '', `the studio holds the lease (${status.leaseHolder})`);

    // Drag from the left of the object to its middle.
    const at = await page.evaluate(() => {
      const v = window.rheo.view;
      const o = [...v.objects.values()][0];
      const c = o.geometry.boundingSphere.center.clone().project(v.camera);
      const r = v.canvas.getBoundingClientRect();
      return [r.left + ((c.x + 1) / 2) * r.width, r.top + ((1 - c.y) / 2) * r.height, r.width];
    });
    const before = await page.evaluate(() => window.rheo.lastFrame().tool.devicePose.position);
    await page.mouse.move(at[0] - at[2] * 0.3, at[1] - 60);
    await page.mouse.down();
    for (let i = 1; i <= 10; i++) await page.mouse.move(at[0] - at[2] * 0.3 * (1 - i / 10), at[1] - 60 + i * 6);
    await sleep(800);
    const after = await page.evaluate(() => window.rheo.lastFrame().tool.devicePose.position);
    await page.mouse.up();
    const moved = Math.hypot((after.x || 0) - (before.x || 0), (after.y || 0) - (before.y || 0), (after.z || 0) - (before.z || 0));
    assert(moved > 0.01, `the tool followed the mouse (${(moved * 1000).toFixed(1)} mm)`);

    await drag.click(); // stop: the lease is released
    let holder = 'x';
    for (let i = 0; i < 30 && holder; i++) {
      await sleep(100);
      holder = (await pageCall(page, 'rheo.v1.DeviceService/GetDeviceStatus', {})).leaseHolder;
    }
    assert(holder === '', 'the lease is released');
    assert(page.errors.length === 0, `page errors: ${page.errors.join('; ')}`);
  },
  { device: 'network' },
);
