// Browser figures of the web viewer (docs/web.md "Figures"): frame time, and the light-drag-
// to-pixels latency of live mode on loopback, in headless Chromium.
//
//   node bench/web/live_latency.mjs --cli build/clients/lightlink --viewer build/clients/web \
//        --scene clients/demo/cornell_box.gltf [--preset draft] [--moves 20] [--size 640x480] [--json out.json]
//
// Bakes the scene (with --grid on), starts `lightlink serve --http` on free loopback ports,
// opens the page live, then moves one light through `--moves` positions on a circle around
// where it starts, one at a time: each latency is from the page sending the move to the first
// frame drawn with a version that includes it (lightlinkViewer.live.latencies). A scene
// without lights (most game levels) gets one point light at its centre, through --lights.
// Frame time: 20 redraws of the settled view, each waited for (lightlinkViewer.measureFrames).
// Needs tests/node's packages (npm ci --prefix tests/node) and Debian's chromium; no GPU is
// used (SwiftShader), so frame times are the CPU rasteriser's.
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { spawn, execFileSync } from 'node:child_process';
import { fileURLToPath } from 'node:url';

const repo = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '../..');
const { findChromium, launchBrowser } = await import(path.join(repo, 'tests/node/browser.mjs'));

const args = Object.fromEntries(process.argv.slice(2).reduce((a, v, i, all) => (v.startsWith('--') ? [...a, [v.slice(2), all[i + 1]]] : a), []));
for (const k of ['cli', 'viewer', 'scene']) if (!args[k]) { console.error(`--${k} is required`); process.exit(2); }
const moves = Number(args.moves ?? 20), preset = args.preset ?? 'draft';
const [width, height] = (args.size ?? '640x480').split('x').map(Number);
const chromiumPath = findChromium();
if (!chromiumPath) { console.error('no Chromium (apt-get install chromium)'); process.exit(2); }

const work = fs.mkdtempSync(path.join(os.tmpdir(), 'lightlink-webbench-'));
const cli = path.resolve(args.cli), scene = path.resolve(args.scene);
const run = (...a) => execFileSync(cli, a, { stdio: ['ignore', 'pipe', 'inherit'] }).toString();
const bake = path.join(work, 'files', 'level'), cache = path.join(work, 'cache');

// A light to move: the scene's first, or one at the centre of its bounds.
const inspect = JSON.parse(run('inspect', '--json', scene));
const bakeArgs = ['bake', scene, '-o', bake, '--preset', preset, '--grid', 'on', '--quiet'];
const bounds = inspect.bounds_m;
let added = null;
if (Object.values(inspect.lights ?? {}).reduce((s, n) => s + n, 0) === 0) {
  const lo = bounds.min, hi = bounds.max, c = lo.map((v, i) => (v + hi[i]) / 2);
  const size = Math.hypot(...hi.map((v, i) => v - lo[i]));
  added = { id: 'bench_light', type: 'point', position: c, intensity: 2 * size * size, color: [1, 0.95, 0.9] };
  fs.writeFileSync(path.join(work, 'lights.json'), JSON.stringify({ version: 1, lights: [added] }));
  bakeArgs.push('--lights', path.join(work, 'lights.json'));
}
const tBake = performance.now();
run(...bakeArgs);
console.log(`baked ${path.basename(scene)} (${preset}) in ${((performance.now() - tBake) / 1000).toFixed(1)} s`);
fs.mkdirSync(cache);
for (const f of fs.readdirSync(path.join(bake, 'cache'))) fs.copyFileSync(path.join(bake, 'cache', f), path.join(cache, f));

const daemon = spawn(cli, ['serve', '--listen', '127.0.0.1:0', '--port-file', path.join(work, 'port'), '--cache-dir', cache,
  '--scene-root', path.dirname(scene), '--no-restore', '--log-level', 'warn', '--http', '127.0.0.1:0',
  '--http-port-file', path.join(work, 'hport'), '--web-root', path.resolve(args.viewer), '--files', path.join(work, 'files')],
  { stdio: ['ignore', 'inherit', 'inherit'] });
for (let i = 0; i < 300 && !fs.existsSync(path.join(work, 'hport')); ++i) await new Promise((r) => setTimeout(r, 100));
const base = `http://127.0.0.1:${fs.readFileSync(path.join(work, 'hport'), 'utf8').trim()}`;

const browser = await launchBrowser(chromiumPath);
const stats = (v) => {
  const s = [...v].sort((a, b) => a - b);
  return { n: s.length, median: s[Math.floor((s.length - 1) / 2)], p95: s[Math.floor(0.95 * (s.length - 1))], max: s.at(-1) };
};
try {
  const page = await browser.newPage({ viewport: { width, height }, deviceScaleFactor: 1 });
  const tOpen = performance.now();
  await page.goto(`${base}/?bake=/files/level/&live=1&ui=0&width=${width}&height=${height}`);
  await page.waitForFunction(() => document.body.dataset.state !== 'loading', null, { timeout: 600000 });
  const err = await page.evaluate(() => document.body.dataset.error);
  if (err) throw new Error(err);
  await page.waitForFunction(() => window.lightlinkViewer.live.version > 0, null, { timeout: 600000 });
  const firstLive = performance.now() - tOpen;
  const frameMs = await page.evaluate(() => window.lightlinkViewer.measureFrames(20));
  const light = await page.evaluate(() => window.lightlinkViewer.live.lights.lights[0]);
  const r = 0.1 * Math.hypot(...bounds.max.map((v, i) => v - bounds.min[i]));
  for (let i = 0; i < moves; ++i) {
    const a = (2 * Math.PI * i) / moves;
    const p = [light.position[0] + r * Math.cos(a), light.position[1], light.position[2] + r * Math.sin(a)];
    await page.evaluate(([id, pos]) => window.lightlinkViewer.live.moveLight(id, pos), [light.id, p]);
    await page.waitForFunction((n) => window.lightlinkViewer.live.latencies.length >= n, i + 1, { timeout: 600000 });
  }
  const latencies = await page.evaluate(() => window.lightlinkViewer.live.latencies);
  const shown = (await page.evaluate(() => window.lightlinkViewer.live.stages)).slice(-moves);
  const stage = (k) => stats(shown.map((x) => x[k])).median;
  const result = { scene: path.basename(scene), preset, size: [width, height], moves, renderer: 'SwiftShader (headless Chromium)',
                   page_to_first_live_ms: firstLive, frame_ms: frameMs, light_change_to_pixels_ms: stats(latencies),
                   median_stage_ms: { relight: stage('relight_ms'), gateway_write: stage('write_ms'), page_load: stage('load_ms'),
                                      draw: stage('draw_ms') }, latencies_ms: latencies };
  console.log(`${result.scene} ${preset} ${width}x${height}: frame ${frameMs.toFixed(1)} ms; light change to pixels median ` +
              `${result.light_change_to_pixels_ms.median.toFixed(0)} ms, p95 ${result.light_change_to_pixels_ms.p95.toFixed(0)} ms ` +
              `over ${moves} moves; page load to first live version ${(firstLive / 1000).toFixed(1)} s\n  median stages: ` +
              Object.entries(result.median_stage_ms).map(([k, v]) => `${k} ${v.toFixed(1)} ms`).join(', '));
  if (args.json) fs.writeFileSync(args.json, JSON.stringify(result, null, 1));
} finally {
  await browser.close();
  daemon.kill('SIGTERM');
  await new Promise((r) => daemon.on('exit', r));
  fs.rmSync(work, { recursive: true, force: true });
}
