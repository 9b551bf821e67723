// The QC gallery in a real browser (issue 54): Chromium, headless, driven by
// puppeteer-core, opens OUT/index.html from the files (no server), checks the
// table and its sorting and filtering by clicks and keys, follows a
// subject's "3D" link and checks the WebGL picture by its pixels: drawn (not
// the background), and turned by a mouse drag.
//
//     node tests/browser/gallery.js OUT/index.html CHROMIUM NODE_MODULES
//
// Prints one JSON object of what it saw; exits 1 on an error of the page or
// of the browser. The assertions are the caller's (tests/python).
'use strict';
const path = require('path');

const [index, chromium, modules] = process.argv.slice(2);
const {seeView, session} = require('./common');

session(modules, chromium, async (browser, out) => {
  const page = await browser.newPage();
  await page.setViewport({width: 800, height: 600});
  page.on('pageerror', e => out.errors.push(String(e)));
  page.on('console', m => { if (m.type() === 'error') out.errors.push(m.text()); });
  await page.goto('file://' + path.resolve(index), {waitUntil: 'load'});
  const ids = () => page.$$eval('#t tbody tr', rs => rs.filter(r => r.style.display !== 'none').map(r => r.cells[0].textContent));
  out.rows = await ids();
  out.failed = await page.$$eval('#t tbody tr.failed', rs => rs.length);
  // Sorting by a click on the "streamlines" header, twice (one way, then the other).
  const header = await page.$$('#t thead th');
  await header[2].click();
  out.sorted_up = await page.$$eval('#t tbody tr', rs => rs.map(r => r.cells[2].textContent));
  await header[2].click();
  out.sorted_down = await page.$$eval('#t tbody tr', rs => rs.map(r => r.cells[2].textContent));
  // Filtering by typing.
  await page.type('#filter', out.rows[0]);
  out.filtered = await ids();
  await page.$eval('#filter', e => { e.value = ''; e.dispatchEvent(new Event('input')); });
  // By subject again (a click on its header), then the first one's 3D view, by its link.
  await header[0].click();
  out.by_subject = await ids();
  out.links_3d = await page.$$eval('a.view3d', as => as.length);
  await Promise.all([page.waitForNavigation({waitUntil: 'load'}), page.click('a.view3d')]);
  out.view_url = page.url();
  const seen = await seeView(page);
  out.view_error = seen.error;
  for (const k of ['info', 'parts', 'before', 'after', 'frames']) out[k] = seen[k];
});
