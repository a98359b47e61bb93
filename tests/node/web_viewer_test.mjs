// The browser viewer (clients/web, docs/web.md) against `lightlink render`: bakes the demo
// scene (draft preset, with its grid; L2, L1 and L0 encodings), renders fixed cameras with `lightlink render`, opens
// the built page (argv[2]) on the same bake and cameras in headless Chromium (SwiftShader's
// WebGL 2), screenshots it and compares the lit pixels (those either picture draws) of the two
// 8-bit sRGB images: the per-pixel difference is the mean over R, G, B of |page - render|,
// its mean and 95th percentile must stay within the tolerances below. On failure the two
// pictures and the difference are kept (paths printed). Then bad URLs: the page must say what
// is wrong.
// Exit 77 (skip) only when no Chromium binary exists.
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { execFileSync } from 'node:child_process';
import { PNG } from 'pngjs';
import { findChromium, launchBrowser } from './browser.mjs';
import { serveFolders } from './static_server.mjs';

// Measured (docs/web.md "Comparison", 2 cores, SwiftShader): room mean 0.10, p95 0.33; probe
// mean 0.28, p95 0.67 (of 255). What remains is where the two rasterise differently (render
// traces one ray per pixel centre) and the sphere's shadow rays, which the page does not
// trace. The tolerances are about 4x that; each broken term measured once lies far beyond
// them: the SH evaluated as L00 only (room mean 7.9, p95 20.7; probe 31.9, 76.7), without
// band 2 (room 4.5, 14.3), the grid not read (room mean 2.3; probe 74.6, 166).
const TOLERANCE = { mean: 1.0, p95: 3 };
// The room from off the axis (lightmapped walls and blocks seen at many normals), and a
// close-up that the grid-lit dynamic sphere fills.
const VIEWS = {
  room: { eye: [0.36, 0.33, -0.8], target: [0.26, 0.26, 0.28], fov: 42, width: 320, height: 240 },
  probe: { eye: [0.24, 0.27, 0.0], target: [0.186, 0.225, 0.169], fov: 35, width: 240, height: 240 },
};

const fail = (msg) => { console.error(`FAIL: ${msg}`); process.exit(1); };
const viewerDir = process.argv[2];
const chromiumPath = findChromium();
if (!chromiumPath) {
  console.log('SKIP: no Chromium binary (install Debian\'s chromium, or set LIGHTLINK_CHROMIUM)');
  process.exit(77);
}
if (!viewerDir || !fs.existsSync(path.join(viewerDir, 'viewer.js')))
  fail(`no built viewer in '${viewerDir}' (build the web_viewer target)`);
const cli = process.env.LIGHTLINK_CLI, source = process.env.LIGHTLINK_SOURCE_DIR;
if (!cli || !source) fail('LIGHTLINK_CLI and LIGHTLINK_SOURCE_DIR must be set (ctest sets them)');
const work = fs.mkdtempSync(path.join(os.tmpdir(), 'lightlink-web-'));
// Each encoding's bake (docs/outputs.md), with the views compared on it: the page reads the
// 9 SH files of L2, the 4 of L1, or the L0 irradiance.exr alone.
const BAKES = { l2: ['room', 'probe'], l1: ['room'], l0: ['room'] };
const run = (...args) => execFileSync(cli, args, { stdio: ['ignore', 'pipe', 'inherit'] }).toString();
for (const encoding of Object.keys(BAKES))
  run('bake', path.join(source, 'clients/demo/cornell_box.gltf'), '-o', path.join(work, encoding), '--preset', 'draft',
      '--grid', 'on', '--encoding', encoding, '--quiet');
const vec = (v) => v.join(',');
const server = await serveFolders({ '/viewer/': viewerDir, '/bake/': work });
const browser = await launchBrowser(chromiumPath);

// One view: `lightlink render` and the page's screenshot, compared. Returns whether it passed.
async function compareView(encoding, view) {
  const c = VIEWS[view], name = `${encoding}_${view}`, bake = path.join(work, encoding);
  const reference = path.join(work, `${name}_render.png`);
  process.stdout.write(run('render', path.join(bake, 'cornell_box_lm.gltf'), '--bake', bake, '-o', reference,
    '--eye', ...c.eye.map(String), '--target', ...c.target.map(String), '--fov', String(c.fov),
    '--width', String(c.width), '--height', String(c.height)));
  const url = `http://127.0.0.1:${server.address().port}/viewer/index.html?bake=/bake/${encoding}/&ui=0` +
    `&eye=${vec(c.eye)}&target=${vec(c.target)}&fov=${c.fov}&width=${c.width}&height=${c.height}`;
  const page = await browser.newPage({ viewport: { width: c.width, height: c.height }, deviceScaleFactor: 1 });
  page.on('console', (m) => { if (m.type() === 'error') console.log(`page error: ${m.text()}`); });
  await page.goto(url);
  await page.waitForFunction(() => document.body.dataset.state !== 'loading', null, { timeout: 180000 });
  const error = await page.evaluate(() => document.body.dataset.error);
  if (error) fail(`${name}: the page reports: ${error}`);
  const info = await page.evaluate(() => window.lightlinkViewer);
  const shot = await page.screenshot({ clip: { x: 0, y: 0, width: c.width, height: c.height } });
  await page.close();
  const pagePng = path.join(work, `${name}_page.png`);
  fs.writeFileSync(pagePng, shot);
  console.log(`${name}: page ${info.counts.lightmapped} meshes lightmapped (${info.bands ? `L${info.bands - 1} SH` : 'L0 irradiance'}), ${info.counts.gridLit} grid-lit, ` +
              `exposure ${info.exposure.toPrecision(4)}, frame ${info.frameMs.toFixed(1)} ms (SwiftShader)`);

  const a = PNG.sync.read(fs.readFileSync(reference)), b = PNG.sync.read(shot);
  if (a.width !== b.width || a.height !== b.height) fail(`${name}: page ${b.width}x${b.height}, render ${a.width}x${a.height}`);
  const diffs = [];
  const diffPng = new PNG({ width: a.width, height: a.height });
  let onlyOne = 0;
  for (let i = 0; i < a.width * a.height; ++i) {
    const o = 4 * i;  // pngjs gives RGBA for both
    const litA = a.data[o] + a.data[o + 1] + a.data[o + 2] > 0, litB = b.data[o] + b.data[o + 1] + b.data[o + 2] > 0;
    let d = 0;
    for (let ch = 0; ch < 3; ++ch) d += Math.abs(a.data[o + ch] - b.data[o + ch]) / 3;
    if (litA || litB) diffs.push(d);
    if (litA !== litB) ++onlyOne;
    diffPng.data.fill(Math.min(255, Math.round(8 * d)), o, o + 3);
    diffPng.data[o + 3] = 255;
  }
  if (diffs.length < 0.25 * a.width * a.height) fail(`${name}: only ${diffs.length} lit pixels: the camera misses the scene`);
  diffs.sort((x, y) => x - y);
  const mean = diffs.reduce((s, d) => s + d, 0) / diffs.length, p95 = diffs[Math.floor(0.95 * (diffs.length - 1))];
  console.log(`${name}: lit pixels ${diffs.length} (${onlyOne} lit in one picture only); |page - render| mean ${mean.toFixed(3)}, ` +
              `p95 ${p95.toFixed(2)}, max ${diffs[diffs.length - 1].toFixed(1)} (8-bit sRGB; tolerance mean ${TOLERANCE.mean}, p95 ${TOLERANCE.p95})`);
  if (mean <= TOLERANCE.mean && p95 <= TOLERANCE.p95) return true;
  const diffFile = path.join(work, `${name}_diff.png`);
  fs.writeFileSync(diffFile, PNG.sync.write(diffPng));
  console.error(`FAIL: ${name}: the page differs from lightlink render beyond the tolerance; kept ${reference}, ${pagePng}, ${diffFile} (8x difference)`);
  return false;
}

// Bad input: the page names what is wrong instead of drawing nothing.
async function expectError(query, wanted) {
  const page = await browser.newPage();
  await page.goto(`http://127.0.0.1:${server.address().port}/viewer/index.html${query}`);
  await page.waitForFunction(() => document.body.dataset.state !== 'loading', null, { timeout: 60000 });
  const error = await page.evaluate(() => document.body.dataset.error ?? '');
  await page.close();
  if (!error.includes(wanted)) fail(`page${query}: error '${error}', expected one saying '${wanted}'`);
  console.log(`ok   page${query}: ${error}`);
}

let passed = true;
try {
  for (const [encoding, views] of Object.entries(BAKES))
    for (const view of views) passed = (await compareView(encoding, view)) && passed;
  await expectError('', 'no bake folder');
  await expectError('?bake=/bake/l2/&eye=1,2', 'URL parameter eye=1,2');
  await expectError('?bake=/bake/missing/', '/bake/missing/report.json: HTTP 404');
} finally {
  await browser.close();
  server.close();
}
if (!passed) process.exit(1);
if (!process.env.LIGHTLINK_KEEP) fs.rmSync(work, { recursive: true, force: true });
console.log('ok   the page matches lightlink render');
