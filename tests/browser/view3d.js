// 3D views in a real browser (issue 54): Chromium, headless, driven by
// puppeteer-core, opens each page given (a notebook's view3d() page, from
// its file), waits until the viewer has drawn every part, and reports the
// WebGL picture by its pixels, before and after a mouse drag.
//
//     node tests/browser/view3d.js CHROMIUM NODE_MODULES PAGE.html...
//
// Prints one JSON object, {pages: [...], errors: [...]}; exits 1 on an error
// of a page or of the browser. The assertions are the caller's (tests/python).
'use strict';
const path = require('path');
const {seeView, session} = require('./common');

const [chromium, modules, ...pages] = process.argv.slice(2);

session(modules, chromium, async (browser, out) => {
  out.pages = [];
  for (const file of pages) {
    const page = await browser.newPage();
    await page.setViewport({width: 800, height: 600});
    page.on('pageerror', e => out.errors.push(file + ': ' + String(e)));
    page.on('console', m => { if (m.type() === 'error') out.errors.push(file + ': ' + m.text()); });
    await page.goto('file://' + path.resolve(file), {waitUntil: 'load'});
    out.pages.push({file, ...await seeView(page)});
    await page.close();
  }
});
