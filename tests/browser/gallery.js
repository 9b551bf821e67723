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
const puppeteer = require(path.join(modules, 'puppeteer-core'));

// The picture of the page's WebGL canvas: how many pixels differ from the
// background, and a digest of the pixels (to tell two pictures apart).
async function picture(page) {
  return page.evaluate(() => {
    const gl = document.querySelector('canvas');
    const c = document.createElement('canvas');
    c.width = gl.width, c.height = gl.height;
    const g = c.getContext('2d');
    g.drawImage(gl, 0, 0);
    const d = g.getImageData(0, 0, c.width, c.height).data;
    const bg = [d[0], d[1], d[2]];
    let drawn = 0, hash = 0, coloured = 0;
    for (let i = 0; i < d.length; i += 4) {
      if (Math.abs(d[i] - bg[0]) + Math.abs(d[i + 1] - bg[1]) + Math.abs(d[i + 2] - bg[2]) > 30) drawn++;
      if (Math.max(d[i], d[i + 1], d[i + 2]) - Math.min(d[i], d[i + 1], d[i + 2]) > 60) coloured++;
      hash = (hash * 31 + d[i] + 3 * d[i + 1] + 7 * d[i + 2]) >>> 0;
    }
    return {width: c.width, height: c.height, background: bg, drawn, coloured, hash};
  });
}

(async () => {
  const browser = await puppeteer.launch({
    executablePath: chromium,
    headless: true,
    args: ['--no-sandbox', '--enable-unsafe-swiftshader', '--use-angle=swiftshader', '--window-size=800,600'],
  });
  const out = {errors: []};
  try {
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
    await page.waitForFunction(() => window.hzReady || window.hzError, {timeout: 60000});
    out.view_error = await page.evaluate(() => window.hzError || null);
    out.info = await page.$eval('#info', e => e.textContent);
    out.before = await picture(page);
    // A drag across the canvas turns the view.
    await page.mouse.move(300, 300);
    await page.mouse.down();
    for (let k = 1; k <= 10; ++k) await page.mouse.move(300 + 15 * k, 300 + 3 * k);
    await page.mouse.up();
    await new Promise(r => setTimeout(r, 200));
    out.after = await picture(page);
    out.frames = await page.evaluate(() => window.hzFrames || 0);
  } catch (e) {
    out.errors.push(String(e && e.stack || e));
  } finally {
    await browser.close();
  }
  process.stdout.write(JSON.stringify(out) + '\n');
  process.exit(out.errors.length ? 1 : 0);
})();
