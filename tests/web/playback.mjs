// Playback in the studio (rheod --replay FILE): a recording is made with a real rheod
// (--device sim-spidar-g: an object pressed by the emulated hand, 30 frames/s), that daemon is
// stopped, and a rheod on the same data dir plays the file back. The studio then shows the
// playback bar with the file's name and "REPLAY" in the status line; at the end it says ended and
// Play starts it again; the 3D view gets the recording's frames with the tool; Pause holds the
// time, Step moves it on a frame at a time, the slider seeks, speed 4 runs about 4x; the daemon's
// refusals (a speed out of range, a step while playing; AddToScene and StartRecording while it
// plays back) are shown in words; a viewer's page and a /?view page show the bar without a
// control. With RHEO_DOCS_SCREENSHOTS=1 it writes docs/studio-playback.png (the studio paused in
// the press); otherwise that picture goes to the system's temporary folder.

import { run, startDaemon, openPage, assert, pageCall, sleep, createThroughApi } from './harness.mjs';
import { fileURLToPath } from 'node:url';
import { basename, join } from 'node:path';
import { tmpdir } from 'node:os';

const shot = process.env.RHEO_DOCS_SCREENSHOTS === '1'
  ? fileURLToPath(new URL('../../docs/studio-playback.png', import.meta.url))
  : join(tmpdir(), 'rheo-studio-playback.png');

const square = JSON.stringify({
  width: 400,
  height: 400,
  strokes: [[[100, 100], [300, 100], [300, 300], [100, 300], [100, 100]]],
});

const RECORD_MS = 7000; // the least wall time recorded
const S = 'rheo.v1.RecordingService';
const playback = (page) => pageCall(page, `${S}/GetPlayback`, {});

/** The bar's time text, "12.3 / 45.6 s", as numbers. */
async function shownTime(page) {
  const text = await page.locator('#pb-time').textContent();
  const m = text.match(/^(\d+\.\d) \/ (\d+\.\d) s$/);
  assert(m, `the time reads "12.3 / 45.6 s": "${text}"`);
  return { position: Number(m[1]), duration: Number(m[2]), text };
}

/** Waits until the daemon's Playback satisfies `pred` (polled through the page's connection). */
async function until(page, pred, what, timeoutMs = 15000) {
  const end = Date.now() + timeoutMs;
  let p;
  while (Date.now() < end) {
    p = await playback(page);
    if (pred(p)) return p;
    await sleep(100);
  }
  throw new Error(`timed out waiting for ${what}; the playback: ${JSON.stringify(p)}`);
}

/** Playback seconds per wall second over `ms`, timed on this side (two GetPlayback answers). */
async function rate(page, ms) {
  const a = await playback(page);
  const t0 = Date.now();
  await sleep(ms);
  const b = await playback(page);
  const wall = (Date.now() - t0) / 1000;
  assert(!b.ended, `still playing when measured: ${JSON.stringify(b)}`);
  return { rate: (b.positionS - a.positionS) / wall, from: a.positionS, to: b.positionS, wall };
}

run(
  'web.playback',
  async ({ daemon, browser, args }) => {
    const t0 = Date.now();
    const T = (m) => console.log(`${((Date.now() - t0) / 1000).toFixed(1)} s ${m}`);

    // --- A recording made with a real rheod: an object, the emulated hand pressing it.
    const live = await openPage(browser, `${daemon.url}/`);
    await live.waitForFunction(() => window.rheo.playback, null, { timeout: 10000 });
    assert((await live.evaluate(() => window.rheo.playback.check())) === null, 'a live daemon plays nothing back');
    assert((await live.locator('#playback').count()) === 0, 'a live daemon: no playback bar');
    assert((await live.locator('#st-replay').textContent()) === '', 'a live daemon: no REPLAY');
    const made = await createThroughApi(live, 'square', square, 0.01);
    const placed = made[made.length - 1].sceneObject;
    assert(placed && placed.instanceId, `the object is in the scene: ${JSON.stringify(made[made.length - 1])}`);
    await live.waitForFunction(() => window.rheo.stats().objects === 1, null, { timeout: 20000 });
    await pageCall(live, `${S}/StartRecording`, { name: 'press for playback', framesHz: 30 });
    const started = Date.now();
    await pageCall(live, 'rheo.v1.DeviceService/SimulatedHand', {
      press: { depthM: 0.008, seconds: 1, instanceId: placed.instanceId },
    }).catch((e) => console.log(`(the press was refused: ${e.message}; the recording goes on without it)`));
    // 6 s of frames (180 at 30/s): on a busy machine the loop falls behind the wall clock and
    // the file's time with it, so it records until its /frames count says so (20 s at most).
    for (;;) {
      const running = (await pageCall(live, `${S}/ListRecordings`, {})).recordings.find((r) => r.state === 'RECORDING_STATE_RECORDING');
      if (Number(running?.messageCounts?.['/frames'] || 0) >= 180 || Date.now() - started > 20000) break;
      await sleep(250);
    }
    await sleep(Math.max(0, RECORD_MS - (Date.now() - started))); // and at least this long
    const rec = await pageCall(live, `${S}/StopRecording`, {});
    assert(rec.state === 'RECORDING_STATE_COMPLETE' && rec.file, `complete, with its file: ${JSON.stringify(rec)}`);
    const frames = Number(rec.messageCounts?.['/frames'] || 0);
    assert(frames > 60, `frames recorded: ${JSON.stringify(rec.messageCounts)}`);
    await live.context().close();
    T(`recorded ${rec.file}: ${rec.durationS.toFixed(1)} s, ${frames} frames`);

    // --- The same data dir (its library holds the square), the file played back. The harness's
    // daemon is now this one: its log on a failure, stopped at the end.
    await daemon.kill();
    const replay = await startDaemon(args, { dataDir: daemon.dataDir, extra: ['--replay', rec.file] });
    daemon.proc = replay.proc;
    daemon.exited = null;
    daemon.log += replay.log;
    replay.proc.stdout.on('data', (c) => (daemon.log += c));
    replay.proc.stderr.on('data', (c) => (daemon.log += c));
    replay.proc.once('exit', (c, sig) => (daemon.exited = c ?? sig));
    assert(/playing back .* frames over/.test(replay.log), 'rheod says it plays the file back');

    const page = await openPage(browser, `${replay.url}/`);
    const bar = page.getByRole('region', { name: 'Playback', exact: true });
    await bar.waitFor({ timeout: 15000 });
    const name = basename(rec.file);
    assert((await page.locator('#pb-file').textContent()) === name, `the bar names the file ${name}`);
    assert((await page.locator('#pb-file').getAttribute('title')) === rec.file, 'its path is the tooltip');
    await page.waitForFunction(() => /^REPLAY/.test(document.querySelector('#st-replay').textContent), null, { timeout: 5000 });
    assert(/follows the recording/.test(await bar.textContent()), 'the bar says the scene follows the recording');
    await page.locator('#device-info', { hasText: /^Playing a recording back/ }).waitFor({ timeout: 10000 });
    const p0 = await playback(page);
    const duration = p0.durationS;
    assert(duration >= 4, `at least 4 s of frames to play with: ${JSON.stringify(p0)}`);
    T(`replay page: ${duration.toFixed(1)} s, ${p0.ended ? 'ended' : p0.paused ? 'paused' : 'playing'} at ${p0.positionS.toFixed(1)} s`);

    const toggle = (label) => bar.getByRole('button', { name: label, exact: true });
    const step = bar.getByRole('button', { name: 'Step', exact: true });
    const slider = bar.getByRole('slider', { name: 'Playback position', exact: true });
    const speed = bar.getByRole('combobox', { name: 'Playback speed', exact: true });
    assert(
      JSON.stringify(await speed.locator('option').allTextContents()) === JSON.stringify(['0.25×', '0.5×', '1×', '2×', '4×']),
      `the speeds offered: ${await speed.locator('option').allTextContents()}`,
    );

    // Speed 4 to the end: it pauses there, ended; the bar says so.
    await speed.selectOption('4');
    await until(page, (p) => p.speed === 4, 'speed 4');
    await until(page, (p) => p.ended && p.paused, 'the end', 20000 + 1000 * duration);
    await page.waitForFunction(() => document.querySelector('#pb-state').textContent === 'ended', null, { timeout: 5000 });
    const atEnd = await shownTime(page);
    assert(atEnd.position === atEnd.duration && Math.abs(atEnd.duration - duration) < 0.06, `at the end: ${atEnd.text}`);
    await toggle('Play').waitFor({ timeout: 5000 });
    assert(await step.isDisabled(), 'no Step at the last frame');
    assert(/^REPLAY · ended$/.test(await page.locator('#st-replay').textContent()), 'the status line says it ended');

    // Play at the end starts it again from the start, at 1x; frames with the object and the tool.
    await speed.selectOption('1');
    await until(page, (p) => p.speed === 1, 'speed 1');
    const framesBefore = await page.evaluate(() => window.rheo.stats().frames);
    await toggle('Play').click();
    await until(page, (p) => !p.paused && !p.ended && p.positionS < duration / 2, 'a restart');
    await toggle('Pause').waitFor({ timeout: 5000 });
    assert(await step.isDisabled(), 'Step is disabled while playing');
    // (Play's own answer may still say ended: the playback thread restarts after it; a poll shows it.)
    await page.waitForFunction(() => document.querySelector('#pb-state').textContent === 'playing', null, { timeout: 5000 });
    const r1 = await rate(page, 1000);
    assert(r1.rate > 0.5 && r1.rate < 1.6, `1x: ${JSON.stringify(r1)}`);
    await page.waitForFunction((n) => window.rheo.stats().frames >= n + 10, framesBefore, { timeout: 10000 });
    const seen = await page.evaluate(() => ({
      stats: window.rheo.stats(),
      tool: window.rheo.lastFrame()?.tool?.present,
      pointer: window.rheo.view.tool.group.visible,
    }));
    assert(seen.stats.objects === 1, `the recording's object in the 3D view: ${JSON.stringify(seen)}`);
    assert(seen.tool && seen.pointer, `the recorded tool is drawn: ${JSON.stringify(seen)}`);
    T(`played at ${r1.rate.toFixed(2)}x; ${seen.stats.frames} frames in the page`);

    // The daemon's refusals, in words, in the bar's alert: a step while playing, a speed of
    // 200; the Pause below clears it.
    const alert = page.locator('#pb-alert[role="alert"]');
    await page.evaluate(() => window.rheo.playback.control({ step: true }));
    const stepWords = await alert.textContent();
    assert(/^FAILED_PRECONDITION: step .*pause it first$/.test(stepWords), `a step while playing: ${stepWords}`);
    await page.evaluate(() => window.rheo.playback.control({ speed: 200 }));
    const speedWords = await alert.textContent();
    assert(/^INVALID_ARGUMENT: speed must be in \(0, 100\]/.test(speedWords), `a speed of 200: ${speedWords}`);
    assert(await alert.isVisible(), 'the alert is shown');
    assert((await speed.inputValue()) === '1', 'the selector shows the speed the daemon kept');

    // Pause holds the time; the frames stop.
    await toggle('Pause').click();
    await until(page, (p) => p.paused, 'paused');
    await toggle('Play').waitFor({ timeout: 5000 });
    assert((await alert.textContent()) === '', 'a control that worked clears the alert');
    await page.waitForFunction(() => !document.querySelector('#pb-step').disabled, null, { timeout: 5000 });
    await sleep(400); // the last poll before the pause has been drawn over
    const held = await shownTime(page);
    const heldAt = await playback(page);
    await sleep(1000);
    const still = await shownTime(page);
    const stillAt = await playback(page);
    assert(still.text === held.text && stillAt.positionS === heldAt.positionS, `paused, the time holds: ${held.text}, then ${still.text}`);
    assert((await page.locator('#pb-state').textContent()) === 'paused', 'the bar says paused');

    // Step: the next recorded frame each time, still paused; the page gets each one.
    const framesPaused = await page.evaluate(() => window.rheo.stats().frames);
    for (let i = 0; i < 6; i++) {
      const before = await playback(page);
      await step.click();
      await until(page, (p) => BigInt(p.tick) > BigInt(before.tick), `step ${i + 1}`, 5000);
    }
    const stepped = await until(page, (p) => p.positionS > heldAt.positionS + 0.15, 'six frames on');
    assert(stepped.paused && stepped.positionS < heldAt.positionS + 0.3, `six steps, one frame each (1/30 s): ${heldAt.positionS} -> ${stepped.positionS}`);
    await page.waitForFunction((t) => document.querySelector('#pb-time').textContent.startsWith(t), stepped.positionS.toFixed(1), { timeout: 5000 });
    assert((await shownTime(page)).text !== held.text, 'the time text moved on');
    await page.waitForFunction((n) => window.rheo.stats().frames > n, framesPaused, { timeout: 5000 });

    // The slider: a click at a tenth of its track seeks there; the time says where.
    const box = await slider.boundingBox();
    await page.mouse.click(box.x + box.width * 0.1, box.y + box.height / 2);
    const asked = Number(await slider.inputValue());
    assert(asked > 0 && asked < duration * 0.25, `the slider moved to about a tenth: ${asked} of ${duration}`);
    const sought = await until(page, (p) => Math.abs(p.positionS - asked) < 0.1, `a seek to ${asked}`);
    assert(sought.paused, 'a seek keeps it paused');
    await page.waitForFunction(
      (v) => Math.abs(Number(document.querySelector('#pb-time').textContent.split(' ')[0]) - v) <= 0.15,
      asked,
      { timeout: 5000 },
    );
    T(`sought to ${asked.toFixed(2)} s: ${(await shownTime(page)).text}`);

    // Speed 4: about four recorded seconds a second.
    await speed.selectOption('4');
    await until(page, (p) => p.speed === 4, 'speed 4');
    await toggle('Play').click();
    await until(page, (p) => !p.paused, 'playing');
    const r4 = await rate(page, 800);
    assert(r4.rate > 2.6 && r4.rate < 5.6, `4x: ${JSON.stringify(r4)}`);
    T(`played at ${r4.rate.toFixed(2)}x`);

    // While it plays back, the scene follows the file: Add to scene (the library) and Record are
    // refused with the daemon's words.
    await page.getByRole('button', { name: 'Add square to scene', exact: true }).click();
    const pad = page.locator('#pad-alert');
    await pad.filter({ hasText: /playing back/ }).waitFor({ timeout: 10000 });
    const addWords = await pad.textContent();
    assert(
      /^Stored “square”, but it was not added to the scene\.\nFAILED_PRECONDITION: rheod is playing back \S+ \(--replay\): the scene follows the recording/.test(addWords),
      `AddToScene refused in words: ${addWords}`,
    );
    assert(!/not ready for this/.test(addWords), `no misleading hint: ${addWords}`);
    await page.getByRole('button', { name: 'Record', exact: true }).click();
    await page.locator('#rec-alert').filter({ hasText: /playing back/ }).waitFor({ timeout: 10000 });
    const recWords = await page.locator('#rec-alert').textContent();
    assert(/^FAILED_PRECONDITION: rheod is playing back \S+ \(--replay\)/.test(recWords), `StartRecording refused: ${recWords}`);
    const scene = await pageCall(page, 'rheo.v1.SceneService/GetScene', {});
    assert((scene.objects || []).length === 1, `only the recording's object in the scene: ${(scene.objects || []).length}`);
    T('refusals shown');

    // A viewer's page and a /?view page: the bar with the file, the position and the time, and
    // no control in the document.
    const token = (await pageCall(page, 'rheo.v1.AuthService/CreateToken', { name: 'vera', role: 'ROLE_VIEWER' })).token;
    const watchers = [
      ['viewer', await openPage(browser, `${replay.url}/`, { token })],
      ['/?view', await openPage(browser, `${replay.url}/?view`)],
    ];
    for (const [who, w] of watchers) {
      const vBar = w.getByRole('region', { name: 'Playback', exact: true });
      await vBar.waitFor({ timeout: 15000 });
      // Seek while paused: the page must come to show 0.5 s however late its frames arrive (a
      // seek while playing left a window of one second, which a loaded machine can miss).
      await pageCall(page, `${S}/ControlPlayback`, { speed: 1, seekS: 0.5, paused: true });
      assert((await w.locator('#pb-file').textContent()) === name, `${who}: the file`);
      await w.waitForFunction(() => /^REPLAY/.test(document.querySelector('#st-replay').textContent), null, { timeout: 10000 });
      await w.waitForFunction(() => Number(document.querySelector('#pb-time').textContent.split(' ')[0]) < 1.0, null, { timeout: 10000 });
      await pageCall(page, `${S}/ControlPlayback`, { paused: false });
      const a = await shownTime(w);
      await w.waitForFunction((t) => document.querySelector('#pb-time').textContent !== t, a.text, { timeout: 10000 });
      const b = await shownTime(w);
      assert(b.position > a.position, `${who}: the time runs: ${a.text}, then ${b.text}`);
      assert((await vBar.getByRole('progressbar', { name: 'Playback position', exact: true }).count()) === 1, `${who}: the position as a bar`);
      const counts = await w.evaluate(() => ({
        inputs: document.querySelectorAll('input, select, textarea').length,
        buttons: document.querySelectorAll('button').length,
      }));
      assert(counts.inputs === 0 && counts.buttons === 0, `${who}: no controls: ${JSON.stringify(counts)}`);
      assert(!/<template/.test(await w.content()), `${who}: no template left in the document`);
    }
    await watchers[0][1].screenshot({ path: join(tmpdir(), 'rheo-studio-playback-viewer.png') });
    const denied = await watchers[0][1]
      .evaluate(() => window.rheo.rpc.call('rheo.v1.RecordingService/ControlPlayback', { paused: true }))
      .then(() => null, (e) => e.message);
    assert(/needs the operator role; token 'vera' is a viewer/.test(denied || ''), `a viewer's ControlPlayback refused: ${denied}`);
    T('watchers');

    // The picture: the studio paused in the press (the tool on the object), clear alerts aside.
    await pageCall(page, `${S}/ControlPlayback`, { paused: true, seekS: duration * 0.8 });
    await until(page, (p) => p.paused && Math.abs(p.positionS - duration * 0.8) < 0.1, 'the picture frame');
    await page.evaluate(() => {
      document.querySelector('#rec-alert').textContent = '';
      document.querySelector('aside.left').scrollTop = 0;
      document.querySelector('aside.right').scrollTop = 0;
    });
    await sleep(1200);
    const contact = await page.evaluate(() => window.rheo.lastFrame()?.tool?.inContact);
    await page.screenshot({ path: shot });
    T(`screenshot ${shot} (tool ${contact ? 'in contact' : 'not in contact'})`);

    for (const p of [page, ...watchers.map(([, w]) => w)]) assert(p.errors.length === 0, `page errors: ${p.errors.join('; ')}`);
  },
  { device: 'sim-spidar-g' },
);
