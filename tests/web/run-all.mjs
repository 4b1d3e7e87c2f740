// Runs every studio browser test one after another (what ctest -L web runs), for a checkout
// without a CMake build directory at hand:
//   node tests/web/run-all.mjs [--rheod PATH] [--web-root DIR] [--chromium PATH]

import { spawnSync } from 'node:child_process';
import { fileURLToPath } from 'node:url';

const TESTS = ['create', 'params', 'viewers', 'refusal', 'viewonly', 'reconnect', 'tool', 'press', 'cancel', 'picture', 'record', 'playback'];
let passed = 0;
let failed = 0;
for (const name of TESTS) {
  const file = fileURLToPath(new URL(`./${name}.mjs`, import.meta.url));
  const r = spawnSync(process.execPath, [file, ...process.argv.slice(2)], { encoding: 'utf8', timeout: name === 'record' || name === 'playback' ? 240000 : 120000 });
  const out = `${r.stdout || ''}${r.stderr || ''}`;
  if (r.status === 0) {
    passed++;
    console.log(out.split('\n').find((l) => l.startsWith('ok ')) || `ok web.${name}`);
  } else {
    failed++;
    console.log(out.trim() || `not ok web.${name} (${r.signal || r.status})`);
  }
}
console.log(`${passed} passed, ${failed} failed`);
process.exit(failed ? 1 : 0);
