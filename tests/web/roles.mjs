// Tokens in the studio: a page without a token shows the sign-in form and the daemon's words;
// a viewer's token gets the watch-only page even at the studio's address, and what it sends
// anyway (a delete, a parameter change, a pause) is refused by the daemon, nothing changes.

import { run, openPage, assert, createThroughApi } from './harness.mjs';

const square = JSON.stringify({
  width: 400,
  height: 400,
  strokes: [[[100, 100], [300, 100], [300, 300], [100, 300], [100, 100]]],
});

run('web.roles', async ({ daemon, browser }) => {
  // The admin's page makes an object and a viewer token.
  const admin = await openPage(browser, `${daemon.url}/`);
  const made = await createThroughApi(admin, 'square', square, 0.01);
  const object = made.find((p) => p.object)?.object;
  assert(object && object.id, 'the admin made an object');
  const created = await admin.evaluate(() =>
    window.rheo.rpc.call('rheo.v1.AuthService/CreateToken', { name: 'vera', role: 'ROLE_VIEWER' }),
  );
  assert(/^rheo_[0-9a-f]{64}$/.test(created.token), `a 256-bit token: ${created.token}`);
  assert((await admin.locator('#who').textContent()) === 'admin (admin)', 'the admin page says who it is');

  // No token: the sign-in form with the daemon's reason, and no studio panels.
  const anon = await openPage(browser, `${daemon.url}/`, { token: '' });
  await anon.waitForSelector('#sign-in', { timeout: 10000 });
  const reason = await anon.locator('#sign-in-reason').textContent();
  assert(/needs an access token/.test(reason), `the reason in words: ${reason}`);
  assert((await anon.getByRole('button', { name: 'Create', exact: true }).count()) === 0, 'no Create');
  assert((await anon.locator('#mode').textContent()) === 'sign in', 'the mode says sign in');
  // Signing in with the viewer token (the form reloads the page with it).
  await anon.getByLabel('Access token').fill(created.token);
  await anon.getByRole('button', { name: 'Use this token' }).click();
  await anon
    .waitForFunction(() => window.rheo && window.rheo.identity && window.rheo.identity.name === 'vera', null, {
      timeout: 15000,
    })
    .catch(async (e) => {
      const state = await anon.evaluate(() => ({
        url: location.href,
        identity: window.rheo && window.rheo.identity,
        who: document.querySelector('#who')?.textContent,
        stored: localStorage.getItem('rheo.token')?.slice(0, 9),
      }));
      throw new Error(`${e.message}; page: ${JSON.stringify(state)}; vera ${created.token.slice(0, 9)} admin ${daemon.token.slice(0, 9)}`);
    });

  // The viewer's page at the studio's address: watch-only.
  const viewer = await openPage(browser, `${daemon.url}/`, { token: created.token });
  assert(await viewer.evaluate(() => window.rheo.viewOnly), 'a viewer token gets the watch-only page');
  assert((await viewer.locator('#mode').textContent()) === 'viewer', 'the mode says viewer');
  assert((await viewer.locator('#who').textContent()) === 'vera (viewer)', 'the page says who it is');
  const counts = await viewer.evaluate(() => ({
    inputs: document.querySelectorAll('input, select, textarea').length,
    buttons: document.querySelectorAll('button').length,
  }));
  assert(counts.inputs === 0 && counts.buttons === 0, `no editing controls: ${JSON.stringify(counts)}`);
  await viewer.waitForFunction(() => window.rheo.stats().frames > 3, null, { timeout: 10000 });

  // What a viewer's page sends anyway is refused by the daemon, in words.
  const tries = await viewer.evaluate(async (id) => {
    const out = {};
    const attempt = async (name, method, request) => {
      try {
        await window.rheo.rpc.call(method, request);
        out[name] = { code: 0 };
      } catch (e) {
        out[name] = { code: e.code, message: e.message };
      }
    };
    await attempt('delete', 'rheo.v1.ObjectService/DeleteObject', { id });
    await attempt('params', 'rheo.v1.SceneService/SetParameters', {
      instanceId: 1,
      parameters: [{ name: 'k_v', value: 1 }],
    });
    await attempt('pause', 'rheo.v1.SceneService/Control', { command: 'RUN_COMMAND_PAUSE' });
    await attempt('token', 'rheo.v1.AuthService/CreateToken', { name: 'mine', role: 'ROLE_ADMIN' });
    return out;
  }, object.id);
  for (const [name, r] of Object.entries(tries)) {
    assert(r.code === 7, `${name} refused with PERMISSION_DENIED: ${JSON.stringify(r)}`);
    assert(/needs the (operator|admin) role; token 'vera' is a viewer/.test(r.message), `${name} in words: ${r.message}`);
  }
  // Nothing changed: the object is stored, the scene runs.
  const after = await admin.evaluate(() => window.rheo.rpc.call('rheo.v1.ObjectService/ListObjects', {}));
  assert(after.objects.some((o) => o.id === object.id), 'the object is still stored');
  const frame = await admin.evaluate(() => window.rheo.lastFrame());
  assert(!frame.paused, 'the scene is not paused');
  for (const p of [admin, anon, viewer]) assert(p.errors.length === 0, `page errors: ${p.errors.join('; ')}`);
});
