// --device sim-spidar-g: "Press here", then a click on the object presses the emulated hand into
// it (SimulatedHand); frames show the tool in contact with that object and a force on the hand,
// and the 3D view labels it in N.

import { run, openPage, assert } from './harness.mjs';
import { readFileSync } from 'node:fs';
import { fileURLToPath } from 'node:url';

const sample = readFileSync(fileURLToPath(new URL('../../samples/ellipse.json', import.meta.url)), 'utf8');

run(
  'web.press',
  async ({ daemon, browser }) => {
    const page = await openPage(browser, `${daemon.url}/`);
    const progress = await page.evaluate(
      (strokesJson) =>
        window.rheo.rpc.collect('rheo.v1.ObjectService/CreateObject', {
          name: 'ellipse',
          sketch: { strokesJson },
          meshOptions: { resolution: 0.016 },
          addToScene: true,
        }),
      sample,
    );
    const inst = progress[progress.length - 1].sceneObject.instanceId;
    await page.waitForFunction(() => window.rheo.stats().objects === 1, null, { timeout: 20000 });
    await page.getByRole('button', { name: 'Press here', exact: true }).click();
    const at = await page.evaluate(() => {
      const v = window.rheo.view;
      const o = [...v.objects.values()][0];
      const c = o.geometry.boundingSphere.center.clone().project(v.camera);
      const r = v.canvas.getBoundingClientRect();
      return [r.left + ((c.x + 1) / 2) * r.width, r.top + ((1 - c.y) / 2) * r.height];
    });
    await page.mouse.click(at[0], at[1]);
    await page.waitForFunction(
      (id) => {
        const t = window.rheo.lastFrame()?.tool;
        const f = t?.wrench?.force || {};
        return t?.inContact && t.contactInstanceId === id && Math.hypot(f.x || 0, f.y || 0, f.z || 0) > 0.05;
      },
      inst,
      { timeout: 20000 },
    );
    const label = await page.locator('.force-label').textContent();
    assert(/^\d+\.\d\d N$/.test(label) && Number(label.split(' ')[0]) > 0, `the force is labelled in N (${label})`);
    assert(page.errors.length === 0, `page errors: ${page.errors.join('; ')}`);
  },
  { device: 'sim-spidar-g' },
);
