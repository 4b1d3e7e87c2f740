// The watch-only page (/?view) has the 3D view and the status line and no editing control at
// all in its document: no Sketch pad, no Create, no sliders, no parameter inputs.

import { run, openPage, assert } from './harness.mjs';

run('web.viewonly', async ({ daemon, browser }) => {
  const page = await openPage(browser, `${daemon.url}/?view`);
  assert((await page.getByRole('img', { name: '3D view', exact: true }).count()) === 1, 'the 3D view is there');
  assert((await page.locator('#status').count()) === 1, 'the status line is there');
  for (const [role, name] of [
    ['img', 'Sketch pad'],
    ['button', 'Create'],
    ['button', 'Cancel'],
    ['button', 'Undo'],
    ['button', 'Clear'],
    ['slider', 'Thickness'],
    ['slider', 'Resolution'],
  ])
    assert((await page.getByRole(role, { name, exact: true }).count()) === 0, `no ${role} "${name}"`);
  const html = await page.content();
  assert(!/Sketch pad|id="create"|<template/.test(html), 'not even hidden in the document');
  const counts = await page.evaluate(() => ({
    inputs: document.querySelectorAll('input, select, textarea').length,
    buttons: document.querySelectorAll('button').length,
  }));
  assert(counts.inputs === 0 && counts.buttons === 0, `no inputs or buttons: ${JSON.stringify(counts)}`);
  await page.waitForFunction(() => window.rheo.stats().frames > 3, null, { timeout: 10000 });
  assert(page.errors.length === 0, `page errors: ${page.errors.join('; ')}`);
});
