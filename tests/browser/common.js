// What the browser tests share: Chromium launched headless with a software
// WebGL (SwiftShader), and the picture of a page's WebGL canvas.
'use strict';
const path = require('path');

function launch(modules, chromium) {
  const puppeteer = require(path.join(modules, 'puppeteer-core'));
  return puppeteer.launch({
    executablePath: chromium,
    headless: true,
    args: ['--no-sandbox', '--enable-unsafe-swiftshader', '--use-angle=swiftshader', '--window-size=800,600'],
  });
}

// The picture of the page's WebGL canvas: how many pixels differ from the
// background, how many are strongly coloured, how many warm (red well above
// green and blue), and a digest of the pixels (to tell two pictures apart).
async function picture(page) {
  return page.evaluate(() => {
    const gl = document.querySelector('canvas');
    const c = document.createElement('canvas');
    c.width = gl.width, c.height = gl.height;
    const g = c.getContext('2d');
    g.drawImage(gl, 0, 0);
    const d = g.getImageData(0, 0, c.width, c.height).data;
    const bg = [d[0], d[1], d[2]];
    let drawn = 0, hash = 0, coloured = 0, warm = 0;
    for (let i = 0; i < d.length; i += 4) {
      if (Math.abs(d[i] - bg[0]) + Math.abs(d[i + 1] - bg[1]) + Math.abs(d[i + 2] - bg[2]) > 30) drawn++;
      if (Math.max(d[i], d[i + 1], d[i + 2]) - Math.min(d[i], d[i + 1], d[i + 2]) > 60) coloured++;
      if (d[i] > d[i + 1] + 25 && d[i] > d[i + 2] + 25) warm++;
      hash = (hash * 31 + d[i] + 3 * d[i + 1] + 7 * d[i + 2]) >>> 0;
    }
    return {width: c.width, height: c.height, background: bg, drawn, coloured, warm, hash};
  });
}

// A drag across the canvas (which turns an orbiting view), then a pause for
// the frame.
async function drag(page) {
  await page.mouse.move(300, 300);
  await page.mouse.down();
  for (let k = 1; k <= 10; ++k) await page.mouse.move(300 + 15 * k, 300 + 3 * k);
  await page.mouse.up();
  await new Promise(r => setTimeout(r, 200));
}

// What a 3D view page (python/horizon/web.py) shows once it is ready: its
// error, the parts read, its line of text, the picture before and after a
// drag, and the frames drawn.
async function seeView(page) {
  await page.waitForFunction(() => window.hzReady || window.hzError, {timeout: 60000});
  const seen = {};
  seen.error = await page.evaluate(() => window.hzError || null);
  seen.parts = await page.evaluate(() => window.hzParts || 0);
  seen.info = await page.$eval('#info', e => e.textContent);
  seen.before = await picture(page);
  await drag(page);
  seen.after = await picture(page);
  seen.frames = await page.evaluate(() => window.hzFrames || 0);
  return seen;
}

// Runs `body(browser, out)` with Chromium launched, then prints `out` (one
// JSON object; out.errors: the pages' and the browser's errors) and exits
// 1 if there were any.
async function session(modules, chromium, body) {
  const browser = await launch(modules, chromium);
  const out = {errors: []};
  try {
    await body(browser, out);
  } catch (e) {
    out.errors.push(String(e && e.stack || e));
  } finally {
    await browser.close();
  }
  process.stdout.write(JSON.stringify(out) + '\n');
  process.exit(out.errors.length ? 1 : 0);
}

module.exports = {launch, picture, drag, seeView, session};
