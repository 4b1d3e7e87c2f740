// Recordings in the studio: Record (a name, 60 frames/s by default) turns into Stop with the
// elapsed time and the live state; an object is added and run multi-rate (its line in Tune it
// live); a second start is refused with the daemon's words; Stop lists the recording COMPLETE
// with its size; Download saves <name>.mcap, a file that begins (and ends) with the MCAP magic;
// a viewer's page lists it and downloads it but has no control; Delete asks first, then it is
// gone; rheod killed while recording, the page lists it TRUNCATED after the restart. With
// RHEO_DOCS_SCREENSHOTS=1 it writes docs/studio-recordings.png (the studio while a second
// recording runs); otherwise that picture goes to the system's temporary folder, so a test run
// leaves the tracked docs alone.

import { run, startDaemon, openPage, assert, pageCall, sleep, createThroughApi } from './harness.mjs';
import { readFile } from 'node:fs/promises';
import { fileURLToPath } from 'node:url';
import { createRequire } from 'node:module';
import { join } from 'node:path';
import { tmpdir } from 'node:os';

const shot = process.env.RHEO_DOCS_SCREENSHOTS === '1'
  ? fileURLToPath(new URL('../../docs/studio-recordings.png', import.meta.url))
  : join(tmpdir(), 'rheo-studio-recordings.png');
const MAGIC = Buffer.from([0x89, 0x4d, 0x43, 0x41, 0x50, 0x30, 0x0d, 0x0a]); // \x89 MCAP0 \r\n

const square = JSON.stringify({
  width: 400,
  height: 400,
  strokes: [[[100, 100], [300, 100], [300, 300], [100, 300], [100, 100]]],
});

/** Messages per topic in an MCAP file, as Foxglove's reader (@mcap/core) reads its summary. */
async function topicsOf(bytes, webRoot) {
  const require = createRequire(join(webRoot, 'package.json'));
  const { McapIndexedReader } = require('@mcap/core');
  const { loadDecompressHandlers } = require('@mcap/support');
  const readable = {
    size: async () => BigInt(bytes.length),
    read: async (offset, length) => bytes.subarray(Number(offset), Number(offset + length)),
  };
  const reader = await McapIndexedReader.Initialize({ readable, decompressHandlers: await loadDecompressHandlers() });
  const out = {};
  for (const [id, n] of reader.statistics.channelMessageCounts) out[reader.channelsById.get(id).topic] = Number(n);
  return out;
}

const list = (page) => pageCall(page, 'rheo.v1.RecordingService/ListRecordings', {}).then((r) => r.recordings || []);

/** The download a click on `link` starts, with its bytes. */
async function download(page, link) {
  await page.evaluate(() => {
    window.__clicks = [];
    if (window.__clicking) return;
    window.__clicking = true;
    document.addEventListener('click', (e) => window.__clicks.push(`${e.target.tagName} ${e.target.getAttribute('aria-label') || e.target.download || ''} trusted=${e.isTrusted} active=${navigator.userActivation?.isActive} t=${Math.round(performance.now())}`), true);
  });
  const [d] = await Promise.all([
    page.waitForEvent('download', { timeout: 20000 }).catch(async (e) => {
      const alert = await page.locator('#rec-alert').textContent();
      const links = await page.locator('#rec-list a').allTextContents();
      const clicks = await page.evaluate(() => window.__clicks);
      throw new Error(`${e.message}; the panel says: "${alert}", its links: ${JSON.stringify(links)}, clicks: ${JSON.stringify(clicks)}`);
    }),
    link.click(),
  ]);
  const failure = await d.failure();
  assert(!failure, `the download failed: ${failure}`);
  return { name: d.suggestedFilename(), bytes: await readFile(await d.path()) };
}

run('web.record', async ({ daemon, browser, args }) => {
  const page = await openPage(browser, `${daemon.url}/`);
  const panel = page.getByRole('region', { name: 'Recordings', exact: true });
  await panel.waitFor();
  const live = page.locator('#rec-live');
  await page.waitForFunction(() => document.querySelector('#rec-live').textContent === 'Not recording.', null, { timeout: 20000 });
  assert((await page.locator('#rec-list').textContent()).includes('No recordings yet'), 'the list says it is empty');
  const fps = page.getByRole('spinbutton', { name: 'Frames per second', exact: true });
  assert((await fps.inputValue()) === '60', 'frames per second default to 60');

  // Record: the button becomes Stop, the state says what runs.
  await page.getByRole('textbox', { name: 'Recording name', exact: true }).fill('lab session 1');
  await page.getByRole('button', { name: 'Record', exact: true }).click();
  const stop = page.getByRole('button', { name: 'Stop', exact: true });
  await stop.waitFor({ timeout: 20000 });
  await page.waitForFunction(() => /● Recording “lab session 1” · 00:0\d · .* · 60 frames\/s/.test(document.querySelector('#rec-live').textContent), null, {
    timeout: 10000,
  });
  assert((await page.getByRole('button', { name: 'Record', exact: true }).count()) === 0, 'no Record while recording');
  assert((await page.getByRole('textbox', { name: 'Recording name', exact: true }).isDisabled()), 'the name is fixed while recording');
  await page.waitForFunction(() => /^● REC \d\d:\d\d$/.test(document.querySelector('#st-rec').textContent), null, { timeout: 15000 });
  const running = (await list(page)).find((r) => r.state === 'RECORDING_STATE_RECORDING');
  assert(running && running.name === 'lab session 1' && running.framesHz === 60, `the daemon records: ${JSON.stringify(running)}`);
  const runningItem = page.getByRole('article', { name: 'Recording lab session 1', exact: true });
  await runningItem.locator('.rec-state', { hasText: 'RECORDING' }).waitFor({ timeout: 15000 });
  assert((await runningItem.getByRole('link').count()) === 0, 'no download while it is written');

  // An object in the scene (the create test covers the pad), then the same one multi-rate.
  const made = await createThroughApi(page, 'square', square, 0.01);
  const object = made.find((p) => p.object)?.object;
  assert(object && object.id, 'an object was made and added');
  const mr = await pageCall(page, 'rheo.v1.SceneService/AddToScene', {
    objectId: object.id,
    multiRate: 'MULTI_RATE_MODE_ON',
    position: { x: 0.15, y: 0.05, z: 0 },
  });
  assert(mr.multiRate && mr.multiRate.periodTicks > 0, `it runs multi-rate: ${JSON.stringify(mr.multiRate)}`);
  await page.waitForFunction(
    (id) => document.querySelector(`#param-instance option[value="${id}"]`)?.textContent.includes('multi-rate'),
    mr.instanceId,
    { timeout: 15000 },
  );
  await page.getByRole('combobox', { name: 'Instance', exact: true }).selectOption(String(mr.instanceId));
  const line = page.getByRole('note', { name: 'Multi-rate', exact: true });
  await line.waitFor({ timeout: 15000 });
  const words = await line.textContent();
  assert(
    /^multi-rate: the \d+ nodes near the tool every tick, the whole every \d+ ticks \((its last step took|a step predicted at) [\d.]+ m?s\), ([\d.]+ m?s behind|keeping up with) real time$/.test(words),
    `the multi-rate line in words: ${words}`,
  );
  assert(words.includes(`every ${mr.multiRate.periodTicks} ticks`), `its period: ${words}`);

  // A second start while one runs: the daemon's refusal, in words, in the panel.
  await page.evaluate(() => window.rheo.recordings.start({ name: 'second', framesHz: 30 }));
  const alert = page.locator('#rec-alert');
  const refusal = await alert.textContent();
  assert(
    /^FAILED_PRECONDITION: recording rec-\S+ \('lab session 1'\) is running since .*one recording at a time/.test(refusal),
    `the refusal in words: ${refusal}`,
  );
  assert((await list(page)).length === 1, 'nothing else started');

  const clock = async () => {
    const m = (await live.textContent()).match(/ · (\d+):(\d\d) · /);
    assert(m, `the elapsed time is shown: ${await live.textContent()}`);
    return 60 * Number(m[1]) + Number(m[2]);
  };
  const w0 = Date.now();
  const t0 = await clock();
  await sleep(2000);
  const t1 = await clock();
  const wall = (Date.now() - w0) / 1000; // a busy machine answers slowly: the clock keeps time
  assert(t1 - t0 >= 1 && t1 - t0 <= wall + 2, `the elapsed time runs: ${t0} s, then ${t1} s, ${wall} s apart`);
  await stop.click();
  await page.getByRole('button', { name: 'Record', exact: true }).waitFor({ timeout: 15000 });
  const item = page.getByRole('article', { name: 'Recording lab session 1', exact: true });
  await item.locator('.rec-state', { hasText: 'COMPLETE' }).waitFor({ timeout: 20000 });
  const [rec] = await list(page);
  assert(rec.state === 'RECORDING_STATE_COMPLETE' && Number(rec.bytes) > 0, `complete and not empty: ${JSON.stringify(rec)}`);
  assert(rec.durationS >= 2, `it lasted the 2 s: ${rec.durationS}`);
  const itemText = await item.textContent();
  assert(!/ 0 B /.test(itemText) && /\d+(\.\d)? (KiB|MiB)/.test(itemText), `the size is listed: ${itemText}`);
  assert(/no ticks dropped|ticks? dropped/.test(itemText), `the dropped ticks are listed: ${itemText}`);
  assert((await page.locator('#st-rec').textContent()) === '', 'the REC indicator is off');

  // Download: ExportRecording into a Blob saved as <name>.mcap, the file as it is on the daemon.
  const got = await download(page, page.getByRole('link', { name: 'Download lab session 1 as MCAP', exact: true }));
  assert(got.name === 'lab_session_1.mcap', `file name ${got.name}`);
  assert(got.bytes.length === Number(rec.bytes), `all ${rec.bytes} bytes: ${got.bytes.length}`);
  assert(got.bytes.subarray(0, 8).equals(MAGIC), `begins with the MCAP magic: ${got.bytes.subarray(0, 8).toString('hex')}`);
  assert(got.bytes.subarray(-8).equals(MAGIC), 'ends with it (the footer is there)');
  const topics = await topicsOf(got.bytes, args.webRoot);
  for (const [topic, n] of Object.entries(rec.messageCounts || {}))
    assert(topics[topic] === Number(n), `${topic}: ${topics[topic]} messages in the file, ${n} listed`);
  assert(topics['/tool'] > 1000 && topics['/scene'] >= 2 && topics['/frames'] > 60, `what was recorded: ${JSON.stringify(topics)}`);

  // A viewer's page: the list and the download, no control; what it sends anyway is refused.
  const made2 = await pageCall(page, 'rheo.v1.AuthService/CreateToken', { name: 'vera', role: 'ROLE_VIEWER' });
  const viewer = await openPage(browser, `${daemon.url}/`, { token: made2.token });
  await viewer.waitForFunction(() => window.rheo.identity?.role === 'viewer', null, { timeout: 20000 });
  const vItem = viewer.getByRole('article', { name: 'Recording lab session 1', exact: true });
  await vItem.locator('.rec-state', { hasText: 'COMPLETE' }).waitFor({ timeout: 20000 });
  const counts = await viewer.evaluate(() => ({
    inputs: document.querySelectorAll('input, select, textarea').length,
    buttons: document.querySelectorAll('button').length,
  }));
  assert(counts.inputs === 0 && counts.buttons === 0, `a viewer has no controls: ${JSON.stringify(counts)}`);
  const vGot = await download(viewer, viewer.getByRole('link', { name: 'Download lab session 1 as MCAP', exact: true }));
  assert(vGot.bytes.equals(got.bytes), 'the viewer downloads the same file');
  const denied = await viewer.evaluate(async () => {
    const out = {};
    for (const [name, method, req] of [
      ['start', 'StartRecording', {}],
      ['delete', 'DeleteRecording', { id: 'x' }],
    ])
      try {
        await window.rheo.rpc.call(`rheo.v1.RecordingService/${method}`, req);
        out[name] = { code: 0 };
      } catch (e) {
        out[name] = { code: e.code, message: e.message };
      }
    return out;
  });
  for (const [name, r] of Object.entries(denied))
    assert(r.code === 7 && /needs the operator role; token 'vera' is a viewer/.test(r.message), `${name} refused: ${JSON.stringify(r)}`);

  // A second recording, running, for the picture: Stop, the live state, both in the list.
  await page.getByRole('button', { name: 'Record', exact: true }).click();
  await stop.waitFor({ timeout: 20000 });
  await sleep(1500);
  await page.evaluate(() => (document.querySelector('aside.right').scrollTop = 0));
  await page.screenshot({ path: shot });
  await stop.click();
  await page.getByRole('button', { name: 'Record', exact: true }).waitFor({ timeout: 15000 });
  await page.waitForFunction(() => document.querySelectorAll('#rec-list .rec-item.complete').length === 2, null, { timeout: 20000 });
  const second = (await list(page)).find((r) => r.id !== rec.id);
  assert(second.name === second.id, `an unnamed recording is named by its id: ${second.name}`);

  // Delete asks first: dismissed, nothing happens; accepted, it is gone.
  const del = page.getByRole('button', { name: 'Delete recording lab session 1', exact: true });
  let asked = '';
  page.once('dialog', (d) => {
    asked = d.message();
    d.dismiss();
  });
  await del.click();
  await sleep(300);
  assert(/Delete the recording “lab session 1”/.test(asked), `it asks: ${asked}`);
  assert((await list(page)).some((r) => r.id === rec.id), 'dismissed: still there');
  page.once('dialog', (d) => d.accept());
  await del.click();
  await item.waitFor({ state: 'detached', timeout: 20000 });
  const left = await list(page);
  assert(!left.some((r) => r.id === rec.id) && left.length === 1, `deleted: ${JSON.stringify(left.map((r) => r.id))}`);
  await viewer.waitForFunction(() => document.querySelectorAll('#rec-list .rec-item').length === 1, null, { timeout: 20000 });
  assert(/Deleted “lab session 1”/.test(await alert.textContent()), 'the panel says so');

  for (const p of [page, viewer]) assert(p.errors.length === 0, `page errors: ${p.errors.join('; ')}`);
  await viewer.context().close();

  // rheod killed while recording: after its restart (same address and data dir) the page lists
  // the recording TRUNCATED, in words, and still downloads it.
  await pageCall(page, 'rheo.v1.RecordingService/StartRecording', { name: 'cut short' });
  await sleep(2500);
  await daemon.kill('SIGKILL');
  const again = await startDaemon(args, { httpPort: Number(new URL(daemon.url).port), dataDir: daemon.dataDir });
  daemon.proc = again.proc;
  daemon.exited = null;
  again.proc.once('exit', (c, sig) => (daemon.exited = c ?? sig));
  daemon.log += again.log;
  const cut = page.getByRole('article', { name: 'Recording cut short', exact: true });
  await cut.locator('.rec-state', { hasText: 'TRUNCATED' }).waitFor({ timeout: 30000 });
  const cutText = await cut.locator('.rec-error').textContent();
  assert(/^Truncated: rheod ended without stopping it/.test(cutText), `in words: ${cutText}`);
  const cutFile = await download(page, cut.getByRole('link', { name: 'Download cut short as MCAP', exact: true }));
  assert(cutFile.name === 'cut_short.mcap' && cutFile.bytes.subarray(0, 8).equals(MAGIC), 'a truncated file downloads too');
  assert((await page.getByRole('button', { name: 'Record', exact: true }).count()) === 1, 'nothing records now');
});
