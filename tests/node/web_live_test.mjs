// Live mode of the browser viewer (docs/web.md "Live mode") end to end: bakes the demo scene
// (draft, grid, two scenarios), starts `lightlink serve --http` (daemon + gateway on
// loopback), opens the page the gateway serves with live=1 in headless Chromium, then
//  1. moves the light through the page (what a drag does): the pixels get brighter where the
//     light went and darker where it was, and the page's picture matches `lightlink render`
//     of the same version pulled from the daemon (`lightlink pull`), within the viewer test's
//     tolerances;
//  2. moves it with `lightlink set-light` on the same scene: the page follows;
//  3. blends the bake's scenarios from the page: the picture dims as the dim scenario takes over;
//  4. hostile requests are refused (another Host, another Origin, a non-JSON POST, a path
//     out of the served folder, a bad light set);
//  5. the scene closed by another client: the page opens the bake again; SIGTERM stops the
//     whole process.
// Prints the light-change-to-pixels latencies it saw (figures come from bench/web).
// Exit 77 (skip) only when no Chromium binary exists.
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { spawn, execFileSync } from 'node:child_process';
import { PNG } from 'pngjs';
import { findChromium, launchBrowser } from './browser.mjs';

const TOLERANCE = { mean: 1.0, p95: 3 };  // web_viewer_test.mjs's, same renderer and page
const VIEW = { eye: [0.36, 0.33, -0.8], target: [0.26, 0.26, 0.28], fov: 42, width: 320, height: 240 };
const LIGHT = 'WarmBulb';

const fail = (msg) => { console.error(`FAIL: ${msg}`); process.exit(1); };
const viewerDir = process.argv[2];
const chromiumPath = findChromium();
if (!chromiumPath) {
  console.log('SKIP: no Chromium binary (install Debian\'s chromium, or set LIGHTLINK_CHROMIUM)');
  process.exit(77);
}
if (!viewerDir || !fs.existsSync(path.join(viewerDir, 'viewer.js'))) fail(`no built viewer in '${viewerDir}' (build the web_viewer target)`);
const cli = process.env.LIGHTLINK_CLI, source = process.env.LIGHTLINK_SOURCE_DIR;
if (!cli || !source) fail('LIGHTLINK_CLI and LIGHTLINK_SOURCE_DIR must be set (ctest sets them)');

const work = fs.mkdtempSync(path.join(os.tmpdir(), 'lightlink-live-'));
const run = (...args) => execFileSync(cli, args, { stdio: ['ignore', 'pipe', 'inherit'] }).toString();
const files = path.join(work, 'files'), bake = path.join(files, 'demo'), cache = path.join(work, 'cache');
const scene = path.join(source, 'clients/demo/cornell_box.gltf');
// Two scenarios: the bulb at a tenth of its intensity, and at full.
fs.mkdirSync(work, { recursive: true });
fs.writeFileSync(path.join(work, 'dim.json'), JSON.stringify({ version: 1, lights: [{ id: LIGHT, intensity: 0.05 }] }));
fs.writeFileSync(path.join(work, 'full.json'), JSON.stringify({ version: 1, lights: [{ id: LIGHT, intensity: 0.5 }] }));
run('bake', scene, '-o', bake, '--preset', 'draft', '--grid', 'on', '--quiet',
    '--scenario', `dim=${path.join(work, 'dim.json')}`, '--scenario', `full=${path.join(work, 'full.json')}`);
fs.mkdirSync(cache);
for (const f of fs.readdirSync(path.join(bake, 'cache'))) fs.copyFileSync(path.join(bake, 'cache', f), path.join(cache, f));

// The daemon and its gateway in one process, both on free loopback ports.
const daemon = spawn(cli, ['serve', '--listen', '127.0.0.1:0', '--port-file', path.join(work, 'port'), '--cache-dir', cache,
  '--scene-root', path.dirname(scene), '--no-restore', '--http', '127.0.0.1:0', '--http-port-file', path.join(work, 'hport'),
  '--web-root', viewerDir, '--files', files], { stdio: ['ignore', 'inherit', 'pipe'] });
let daemonLog = '';
daemon.stderr.on('data', (d) => { daemonLog += d; });
const exited = new Promise((resolve) => daemon.on('exit', (code, signal) => resolve({ code, signal })));
for (let i = 0; i < 300 && !fs.existsSync(path.join(work, 'hport')); ++i) await new Promise((r) => setTimeout(r, 100));
if (!fs.existsSync(path.join(work, 'hport'))) fail(`lightlink serve did not start:\n${daemonLog}`);
const daemonPort = fs.readFileSync(path.join(work, 'port'), 'utf8').trim();
const httpPort = fs.readFileSync(path.join(work, 'hport'), 'utf8').trim();
const base = `http://127.0.0.1:${httpPort}`;
if (!/viewer is at http:\/\/127\.0\.0\.1:\d+\//.test(daemonLog)) fail(`serve does not print the viewer's URL:\n${daemonLog}`);

const browser = await launchBrowser(chromiumPath);

const luminance = (png) => {
  const l = new Float64Array(png.width * png.height);
  for (let i = 0; i < l.length; ++i) l[i] = (png.data[4 * i] + png.data[4 * i + 1] + png.data[4 * i + 2]) / 3;
  return l;
};
// Mean luminance of the left and right thirds of the picture.
const sides = (png) => {
  const l = luminance(png), w = png.width, third = Math.floor(w / 3);
  let left = 0, right = 0, n = 0;
  for (let y = 0; y < png.height; ++y)
    for (let x = 0; x < third; ++x, ++n) { left += l[y * w + x]; right += l[y * w + w - 1 - x]; }
  return { left: left / n, right: right / n, mean: l.reduce((s, v) => s + v, 0) / l.length };
};

function compare(a, b) {
  const diffs = [];
  for (let i = 0; i < a.width * a.height; ++i) {
    const o = 4 * i;
    const lit = a.data[o] + a.data[o + 1] + a.data[o + 2] > 0 || b.data[o] + b.data[o + 1] + b.data[o + 2] > 0;
    if (!lit) continue;
    let d = 0;
    for (let ch = 0; ch < 3; ++ch) d += Math.abs(a.data[o + ch] - b.data[o + ch]) / 3;
    diffs.push(d);
  }
  diffs.sort((x, y) => x - y);
  return { n: diffs.length, mean: diffs.reduce((s, d) => s + d, 0) / diffs.length, p95: diffs[Math.floor(0.95 * (diffs.length - 1))] };
}

let page;
const shot = async (name) => {
  const png = await page.screenshot({ clip: { x: 0, y: 0, width: VIEW.width, height: VIEW.height } });
  fs.writeFileSync(path.join(work, `${name}.png`), png);
  return PNG.sync.read(png);
};
// Waits until the page shows a version >= `version` (0: any new one after `after`).
const waitVersion = async (version, after = 0) => {
  await page.waitForFunction(([v, a]) => {
    const live = window.lightlinkViewer?.live;
    return live && (live.error || (live.version >= v && live.version > a));
  }, [version, after], { timeout: 120000 });
  const live = await page.evaluate(() => window.lightlinkViewer.live);
  if (live.error) fail(`the page reports: ${live.error}`);
  return live.version;
};

let ok = false;
try {
  page = await browser.newPage({ viewport: { width: VIEW.width, height: VIEW.height }, deviceScaleFactor: 1 });
  page.on('console', (m) => { if (m.type() === 'error') console.log(`page error: ${m.text()}`); });
  const vec = (v) => v.join(',');
  await page.goto(`${base}/?bake=/files/demo/&live=1&ui=0&eye=${vec(VIEW.eye)}&target=${vec(VIEW.target)}&fov=${VIEW.fov}` +
                  `&width=${VIEW.width}&height=${VIEW.height}`);
  await page.waitForFunction(() => document.body.dataset.state !== 'loading', null, { timeout: 180000 });
  const error = await page.evaluate(() => document.body.dataset.error);
  if (error) fail(`the page reports: ${error}`);
  const first = await waitVersion(1);
  const info = await page.evaluate(() => ({ sceneId: window.lightlinkViewer.live.sceneId, token: window.lightlinkViewer.live.sceneToken,
                                            scenarios: window.lightlinkViewer.live.scenarios }));
  console.log(`ok   live: scene ${info.sceneId}, first version ${first}, scenarios ${info.scenarios.join(', ')}`);
  if (info.scenarios.join(',') !== 'dim,full') fail(`scenarios ${info.scenarios}, expected dim, full`);
  const a = await shot('a_start');

  // 1. The page moves the bulb to the box's left side (x small: the picture's right, as the
  //    camera looks along +z from z < 0 with x to the left).
  const left = [0.1, 0.45, 0.25];
  await page.evaluate(([id, p]) => window.lightlinkViewer.live.moveLight(id, p), [LIGHT, left]);
  await page.waitForFunction(() => window.lightlinkViewer.live.latencies.length >= 1, null, { timeout: 120000 });
  const movedVersion = await waitVersion(first + 1);
  const b = await shot('b_page_moved');
  const sa = sides(a), sb = sides(b);
  console.log(`page move: version ${movedVersion}; mean luminance left/right thirds ${sa.left.toFixed(1)}/${sa.right.toFixed(1)} -> ` +
              `${sb.left.toFixed(1)}/${sb.right.toFixed(1)}`);
  if (!(sb.right > 1.15 * sa.right && sb.left < 0.95 * sa.left))
    fail('moving the light to the box\'s left did not brighten the picture\'s right third and darken its left');

  // The same version as files, drawn by `lightlink render` with the moved light (the sphere,
  // lit from the grid, takes its direct light from the page's light position).
  const exposure = String(await page.evaluate(() => window.lightlinkViewer.exposure));
  const checkAgainstRender = (version, position, shotPng, name) => {
    const pulled = path.join(work, `pulled_${name}`);
    run('pull', '--target', `127.0.0.1:${daemonPort}`, '--scene', info.sceneId, '--scene-token', info.token,
        '--version', String(version), '-o', pulled, '--quiet');
    const lights = JSON.parse(fs.readFileSync(path.join(bake, 'lights.json'), 'utf8'));
    lights.lights.find((l) => l.id === LIGHT).position = position;
    fs.writeFileSync(path.join(work, `${name}.json`), JSON.stringify(lights));
    const rendered = path.join(work, `${name}_render.png`);
    run('render', path.join(bake, 'cornell_box_lm.gltf'), '--bake', pulled, '--lights', path.join(work, `${name}.json`), '-o', rendered,
        '--eye', ...VIEW.eye.map(String), '--target', ...VIEW.target.map(String), '--fov', String(VIEW.fov),
        '--width', String(VIEW.width), '--height', String(VIEW.height), '--exposure', exposure, '--quiet');
    const c = compare(PNG.sync.read(fs.readFileSync(rendered)), shotPng);
    console.log(`${name}: page vs render of pulled version ${version}: lit ${c.n}, mean ${c.mean.toFixed(3)}, p95 ${c.p95.toFixed(2)} ` +
                `(tolerance mean ${TOLERANCE.mean}, p95 ${TOLERANCE.p95})`);
    if (!(c.mean <= TOLERANCE.mean && c.p95 <= TOLERANCE.p95)) fail(`${name}: the live page differs from lightlink render (kept ${work})`);
  };
  checkAgainstRender(movedVersion, left, b, 'page_move');

  // 2. Another client moves it to the right side: the page follows.
  const before = await page.evaluate(() => window.lightlinkViewer.live.version);
  run('set-light', LIGHT, '--target', `127.0.0.1:${daemonPort}`, '--scene', info.sceneId, '--scene-token', info.token,
      '--position', '0.45,0.45,0.25', '--wait');
  const cliVersion = await waitVersion(0, before);
  const d = await shot('c_set_light');
  const sd = sides(d);
  console.log(`set-light: version ${cliVersion}; left/right thirds ${sb.left.toFixed(1)}/${sb.right.toFixed(1)} -> ${sd.left.toFixed(1)}/${sd.right.toFixed(1)}`);
  if (!(sd.left > 1.15 * sb.left && sd.right < 0.95 * sb.right)) fail('after set-light the page did not follow the light to the left third');
  // The page learnt the new position from the daemon (GetLights through the gateway): its
  // sphere's direct light agrees with render's too.
  checkAgainstRender(cliVersion, [0.45, 0.45, 0.25], d, 'set_light');

  // 3. Scenario blend from the page: all "dim" is about a tenth of all "full".
  const blend = async (weights) => {
    const v = await page.evaluate(() => window.lightlinkViewer.live.version);
    await page.evaluate((w) => window.lightlinkViewer.live.blendScenarios(w), weights);
    await waitVersion(0, v);
    return sides(await shot(`blend_${Object.values(weights).join('_')}`));
  };
  const full = await blend({ dim: 0, full: 1 }), dim = await blend({ dim: 1, full: 0 });
  console.log(`scenario blend: mean luminance full ${full.mean.toFixed(1)}, dim ${dim.mean.toFixed(1)}`);
  if (!(dim.mean < 0.7 * full.mean)) fail('blending to the dim scenario did not dim the picture');

  // 4. Hostile requests.
  const expectStatus = async (what, status, url, init = {}) => {
    const res = await fetch(url, init);
    const body = await res.text();
    if (res.status !== status) fail(`${what}: HTTP ${res.status} ${body}, expected ${status}`);
    console.log(`ok   ${what}: ${res.status} ${body.slice(0, 120)}`);
  };
  const json = { 'Content-Type': 'application/json' };
  await expectStatus('a form POST', 415, `${base}/api/live/${info.sceneId}/lights`, { method: 'POST', body: 'x=1' });
  await expectStatus('a POST from another origin', 403, `${base}/api/live/${info.sceneId}/lights`,
    { method: 'POST', headers: { ...json, Origin: 'http://evil.example' }, body: '{}' });
  await expectStatus('a bad light set', 400, `${base}/api/live/${info.sceneId}/lights`,
    { method: 'POST', headers: json, body: JSON.stringify({ version: 1, lights: [{ id: LIGHT, intensity: -1 }] }) });
  await expectStatus('a bake outside the files', 404, `${base}/api/live`,
    { method: 'POST', headers: json, body: JSON.stringify({ bake: '/files/../../' }) });
  await expectStatus('a hidden file', 404, `${base}/files/demo/.hidden`);
  const rebinding = await new Promise((resolve) => {
    import('node:http').then(({ request }) => {
      const req = request({ host: '127.0.0.1', port: httpPort, path: '/', headers: { Host: `attacker.example:${httpPort}` } },
        (res) => { res.resume(); resolve(res.statusCode); });
      req.end();
    });
  });
  if (rebinding !== 403) fail(`a request with another Host got ${rebinding}, expected 403`);
  console.log('ok   a request with another Host header: 403');

  // 5. The scene closed under the page (another client, a daemon restart): the page opens the
  //    bake again and goes on live under a new scene id.
  run('close', '--target', `127.0.0.1:${daemonPort}`, '--scene', info.sceneId, '--scene-token', info.token);
  await page.waitForFunction((old) => {
    const live = window.lightlinkViewer.live;
    return live.error || (live.sceneId !== old && live.version > 0);
  }, info.sceneId, { timeout: 120000 });
  const reopened = await page.evaluate(() => window.lightlinkViewer.live.sceneId);
  console.log(`ok   scene ${info.sceneId} closed by another client: the page is live again as ${reopened}`);

  const lat = await page.evaluate(() => window.lightlinkViewer.live.latencies);
  console.log(`light change to pixels (SwiftShader, 2 cores): ${lat.map((x) => x.toFixed(0)).join(', ')} ms`);
  ok = true;
} finally {
  await browser.close();
  daemon.kill('SIGTERM');
  const end = await Promise.race([exited, new Promise((r) => setTimeout(() => r(null), 20000))]);
  if (!end) { daemon.kill('SIGKILL'); fail(`lightlink serve did not stop within 20 s of SIGTERM:\n${daemonLog.slice(-2000)}`); }
  if (ok && end.code !== 0) fail(`lightlink serve exited with ${end.code ?? end.signal}:\n${daemonLog.slice(-2000)}`);
}
if (!process.env.LIGHTLINK_KEEP) fs.rmSync(work, { recursive: true, force: true });
console.log('ok   live mode: page moves, set-light and scenario blends relight the page through the gateway');
