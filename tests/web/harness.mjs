// Shared harness of the studio's browser tests: starts a rheod of its own (fresh data dir, ports
// 0), launches Debian's headless Chromium through playwright-core, and cleans both up. A failure
// prints the daemon's log tail.
//
//   node tests/web/<test>.mjs --rheod PATH --web-root clients/web [--device none|sim-spidar-g|network]

import { spawn } from 'node:child_process';
import { mkdtempSync, readFileSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join, dirname, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';
import { createRequire } from 'node:module';

const here = dirname(fileURLToPath(import.meta.url));
const repo = resolve(here, '..', '..');

export function parseArgs(argv = process.argv.slice(2)) {
  const out = {
    rheod: process.env.RHEOD || join(repo, 'build/dev/server/daemon/rheod'),
    webRoot: join(repo, 'clients/web'),
    chromium: process.env.CHROMIUM || '/usr/bin/chromium',
  };
  for (let i = 0; i < argv.length; i++) {
    const a = argv[i];
    if (a === '--rheod') out.rheod = argv[++i];
    else if (a === '--web-root') out.webRoot = resolve(argv[++i]);
    else if (a === '--chromium') out.chromium = argv[++i];
    else throw new Error(`unknown argument ${a}`);
  }
  return out;
}

/** playwright-core from the studio's own node_modules. */
function playwright(webRoot) {
  const require = createRequire(join(webRoot, 'package.json'));
  return require('playwright-core');
}

export class Daemon {
  constructor(proc, dataDir) {
    this.proc = proc;
    this.dataDir = dataDir;
    this.log = '';
    this.exited = null;
  }

  tail(lines = 40) {
    return this.log.split('\n').slice(-lines).join('\n');
  }

  /** Stops the process but keeps the data dir (for a restart on it). */
  async kill(signal = 'SIGTERM') {
    if (this.exited === null) {
      this.proc.kill(signal);
      await new Promise((r) => (this.exited !== null ? r() : this.proc.once('exit', r)));
    }
  }

  async stop() {
    if (this.exited === null) {
      this.proc.kill('SIGTERM');
      const t = setTimeout(() => this.proc.kill('SIGKILL'), 5000);
      await new Promise((r) => (this.exited !== null ? r() : this.proc.once('exit', r)));
      clearTimeout(t);
    }
    rmSync(this.dataDir, { recursive: true, force: true });
  }
}

/** Starts rheod and waits for its gRPC and http ports in the log. */
export async function startDaemon(args, { device = 'none', extra = [], httpPort = 0, dataDir = null } = {}) {
  dataDir = dataDir || mkdtempSync(join(tmpdir(), 'rheo-web-'));
  const argv = [
    '--listen', '127.0.0.1:0',
    ...(extra.includes('--http') ? [] : ['--http', `127.0.0.1:${httpPort}`]),
    '--web-root', args.webRoot,
    '--data-dir', dataDir,
    '--device', device,
    '--no-realtime',
    '--sim-budget', '0',
    ...extra,
  ];
  const proc = spawn(args.rheod, argv, { stdio: ['ignore', 'pipe', 'pipe'] });
  const d = new Daemon(proc, dataDir);
  const ready = new Promise((resolveReady, reject) => {
    const onData = (chunk) => {
      d.log += chunk.toString();
      const grpc = d.log.match(/listening on (\S+?):(\d+)/);
      const http = d.log.match(/studio at (https?:\/\/[^\s/]+:(\d+))\//);
      if (grpc && http && !d.url) {
        d.grpcPort = Number(grpc[2]);
        d.url = http[1];
        resolveReady(d);
      }
    };
    proc.stdout.on('data', onData);
    proc.stderr.on('data', onData);
    proc.once('exit', (code, sig) => {
      d.exited = code ?? sig;
      reject(new Error(`rheod exited (${code ?? sig}) before it was ready`));
    });
    proc.once('error', reject);
  });
  const timeout = new Promise((_, reject) =>
    setTimeout(() => reject(new Error('rheod did not print "listening on" and "studio at" within 30 s')), 30000),
  );
  try {
    await Promise.race([ready, timeout]);
  } catch (e) {
    e.daemonLog = d.tail();
    if (d.exited === null) proc.kill('SIGKILL');
    throw e;
  }
  // The admin token rheod wrote on its first start: pages open with it unless told otherwise.
  d.token = readFileSync(join(dataDir, 'admin.token'), 'utf8').trim();
  lastToken = d.token;
  return d;
}

export const CHROMIUM_ARGS = [
  '--no-sandbox',
  '--disable-gpu',
  '--disable-quic',
  '--no-first-run',
  '--disable-background-networking',
  '--disable-component-update',
  '--disable-sync',
  // WebGL without a GPU: ANGLE on SwiftShader.
  '--use-angle=swiftshader',
  '--enable-unsafe-swiftshader',
];

export async function launchBrowser(args) {
  const { chromium } = playwright(args.webRoot);
  return chromium.launch({ executablePath: args.chromium, headless: true, args: CHROMIUM_ARGS });
}

let lastToken = '';

/**
 * A page of the studio, with console errors collected (they fail the test). It opens with the
 * last started daemon's admin token in the URL fragment unless `token` is given ('' for none).
 * `ignoreHTTPSErrors`: accept a certificate of a CA the browser does not know (a test's own).
 */
export async function openPage(
  browser,
  url,
  { width = 1440, height = 900, token = undefined, ignoreHTTPSErrors = false } = {},
) {
  const t = token === undefined ? lastToken : token;
  if (t) url += `#token=${encodeURIComponent(t)}`;
  const context = await browser.newContext({ viewport: { width, height }, deviceScaleFactor: 1, ignoreHTTPSErrors });
  const page = await context.newPage();
  page.errors = [];
  page.on('pageerror', (e) => page.errors.push(String(e)));
  page.on('console', (m) => {
    if (m.type() === 'error') page.errors.push(m.text());
  });
  await page.goto(url);
  // Connected, and settled: the page publishes window.rheo.identity (null when signed out) last,
  // once its panels are placed and their handlers attached. Connected alone came first on a
  // loaded machine, and web.picture once chose its file before the studio listened for it.
  await page.waitForFunction(
    () => window.rheo && window.rheo.stats().connected && window.rheo.identity !== undefined,
    null,
    { timeout: 20000 },
  );
  return page;
}

export function assert(cond, msg) {
  if (!cond) throw new Error(`assertion failed: ${msg}`);
}

/** Runs one test: daemon + browser up, `body({daemon, browser, args})`, both torn down. */
export async function run(name, body, options = {}) {
  const args = parseArgs();
  let daemon = null;
  let browser = null;
  const started = Date.now();
  let ok = false;
  try {
    daemon = await startDaemon(args, options);
    browser = await launchBrowser(args);
    await body({ daemon, browser, args });
    ok = true;
  } catch (e) {
    console.error(`FAIL ${name}: ${e.stack || e}`);
    const log = e.daemonLog || (daemon && daemon.tail());
    if (log) console.error(`--- rheod log tail ---\n${log}\n---`);
  } finally {
    if (browser) await browser.close().catch(() => {});
    if (daemon) await daemon.stop().catch(() => {});
  }
  const secs = ((Date.now() - started) / 1000).toFixed(1);
  console.log(ok ? `ok ${name} (${secs} s)` : `not ok ${name} (${secs} s)`);
  console.log(ok ? '1 passed, 0 failed' : '0 passed, 1 failed');
  process.exit(ok ? 0 : 1);
}

/**
 * Draws strokes on the "Sketch pad" with real pointer events (mouse), given in the pad's own
 * sketch pixels (512 x 512).
 */
export async function drawStrokes(page, strokes) {
  const pad = page.getByRole('img', { name: 'Sketch pad', exact: true });
  const box = await pad.boundingBox();
  const size = await pad.evaluate((c) => [c.width, c.height]);
  const at = ([x, y]) => [box.x + (x / size[0]) * box.width, box.y + (y / size[1]) * box.height];
  for (const s of strokes) {
    const [x0, y0] = at(s[0]);
    await page.mouse.move(x0, y0);
    await page.mouse.down();
    for (const p of s.slice(1)) {
      const [x, y] = at(p);
      await page.mouse.move(x, y);
    }
    await page.mouse.up();
  }
}

/** A closed, hand-drawn-like blob (points in sketch pixels), overlapping its start a little. */
export function blob(cx = 256, cy = 256, rx = 150, ry = 105, n = 72) {
  const pts = [];
  for (let i = 0; i <= n + 4; i++) {
    const t = (i / n) * Math.PI * 2;
    const wobble = 1 + 0.04 * Math.sin(3 * t);
    pts.push([cx + rx * wobble * Math.cos(t), cy + ry * wobble * Math.sin(t)]);
  }
  return pts;
}

/** Calls the API through the page's own connection (window.rheo.rpc). */
export function pageCall(page, method, request = {}) {
  return page.evaluate(([m, r]) => window.rheo.rpc.call(m, r), [method, request]);
}

export const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

/**
 * Makes an object through the page's own API connection and adds it to the scene (the create test
 * covers the pad); resolves with CreateObject's progress messages, the object in the last.
 */
export function createThroughApi(page, name, strokesJson, resolution) {
  return page.evaluate(
    ([name, strokesJson, resolution]) =>
      window.rheo.rpc.collect('rheo.v1.ObjectService/CreateObject', {
        name,
        sketch: { strokesJson },
        meshOptions: { resolution },
        addToScene: true,
      }),
    [name, strokesJson, resolution],
  );
}
