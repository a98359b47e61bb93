// The KTX2 delivery step (clients/tools/ktx2/ktx2_encode.mjs) on a bake of the demo: every
// KTX2 it writes parses with ktx-parse as UASTC HDR 4x4 (vkFormat ASTC_4x4_SFLOAT_BLOCK,
// what three.js's KTX2Loader takes as Basis HDR) of its EXR's size with the EXR's lightlink.*
// attributes as key/values, transcodes with three.js's basis transcoder to RGBA half within
// a stated error of the EXR as EXRLoader reads it, and ktx2.json reports its true size. The
// tool refuses a folder that is no bake and names the npm packages when they are missing.
import { execFileSync, spawnSync } from 'node:child_process';
import { mkdtempSync, readFileSync, rmSync, statSync } from 'node:fs';
import { createRequire } from 'node:module';
import { tmpdir } from 'node:os';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';
import { read } from 'ktx-parse';
import { DataUtils, FloatType } from 'three';
import { EXRLoader } from 'three/examples/jsm/loaders/EXRLoader.js';

const cli = process.env.LIGHTLINK_CLI;
const source = process.env.LIGHTLINK_SOURCE_DIR;
const tool = join(source, 'clients/tools/ktx2/ktx2_encode.mjs');
const work = mkdtempSync(join(tmpdir(), 'lightlink-ktx2-'));
let failures = 0;
const fail = (msg) => {
  console.error('FAIL ' + msg);
  failures++;
};

const out = join(work, 'bake');
execFileSync(cli, ['bake', join(source, 'clients/demo/cornell_box.gltf'), '-o', out, '--preset', 'draft', '--encoding', 'l1', '-q'],
             { stdio: 'inherit' });
const run = spawnSync(process.execPath, [tool, out], { encoding: 'utf8' });
if (run.status !== 0) fail(`ktx2_encode exited ${run.status}: ${run.stderr}`);
const report = JSON.parse(readFileSync(join(out, 'ktx2.json'), 'utf8'));
// HDR: the non-negative maps; then the signed band-1 coefficients as ratios to L00 (LDR).
const expected = ['direct.ktx2', 'grid_L00.ktx2', 'irradiance.ktx2', 'lightmap_L00.ktx2', 'grid_L10.ktx2', 'grid_L11.ktx2',
                  'grid_L1m1.ktx2', 'lightmap_L10.ktx2', 'lightmap_L11.ktx2', 'lightmap_L1m1.ktx2'];
if (report.files.map((f) => f.ktx2).join() !== expected.join()) fail(`KTX2 files ${report.files.map((f) => f.ktx2)}, expected ${expected}`);
for (const kept of ['grid_valid.exr', 'valid.exr'])
  if (!report.kept_exr.includes(kept)) fail(`${kept} (validity) is not listed as kept as EXR`);
// The whole L1 set restored from the KTX2s, evaluated: UASTC (HDR L00, 8-bit ratios) measured
// 2 % (lightmap) and 5 % (grid, whose small values the ratio's 8 bits cut coarser).
for (const [kind, limit] of [['lightmap_sh', 0.06], ['grid_sh', 0.12]]) {
  const r = report.irradiance?.[kind];
  if (!r || !(r.rel_rmse < limit)) fail(`${kind}: irradiance from the KTX2s rel RMSE ${r?.rel_rmse}, limit ${limit}`);
  else console.log(`${kind}: irradiance from the KTX2s, rel RMSE ${r.rel_rmse.toFixed(4)} (limit ${limit})`);
}
const ratioScale = [1, 1.7320508, 1.7320508, 1.7320508];

// three.js's basis transcoder, as KTX2Loader's worker runs it (RGBA half where ASTC HDR is unsupported).
const modules = join(dirname(fileURLToPath(import.meta.url)), 'node_modules');
const basisDir = join(modules, 'three/examples/jsm/libs/basis');
const m = { exports: {} };
new Function('module', 'exports', 'require', '__filename', '__dirname', readFileSync(join(basisDir, 'basis_transcoder.js'), 'utf8'))(
  m, m.exports, createRequire(join(basisDir, 'basis_transcoder.js')), join(basisDir, 'basis_transcoder.js'), basisDir);
const basis = await m.exports({ wasmBinary: readFileSync(join(basisDir, 'basis_transcoder.wasm')) });
basis.initializeBasis();

const decodedHalf = {};  // L00 KTX2 (half, top-down) per SH kind, to restore the ratios with
for (const entry of report.files) {
  const bytes = new Uint8Array(readFileSync(join(out, entry.ktx2)));
  if (statSync(join(out, entry.ktx2)).size !== entry.ktx2_bytes) fail(`${entry.ktx2}: ktx2.json says ${entry.ktx2_bytes} bytes`);
  const container = read(bytes);
  const exrBytes = readFileSync(join(out, entry.exr));
  const exr = new EXRLoader().setDataType(FloatType).parse(exrBytes.buffer.slice(exrBytes.byteOffset, exrBytes.byteOffset + exrBytes.byteLength));
  const kv = (k) => new TextDecoder().decode(container.keyValue[k] ?? new Uint8Array()).replace(/\0$/, '');
  if (entry.form === 'ratio_to_L00') {
    checkRatio(entry, bytes, container, exr, kv);
    continue;
  }
  if (container.vkFormat !== 1000066000) fail(`${entry.ktx2}: vkFormat ${container.vkFormat}, not ASTC_4x4_SFLOAT_BLOCK (UASTC HDR 4x4)`);
  if (container.pixelWidth !== exr.width || container.pixelHeight !== exr.height)
    fail(`${entry.ktx2}: ${container.pixelWidth}x${container.pixelHeight}, its EXR ${exr.width}x${exr.height}`);
  if (kv('lightlink.kind') !== exr.header['lightlink.kind'] || kv('lightlink.layout') !== '2')
    fail(`${entry.ktx2}: key/values kind '${kv('lightlink.kind')}' layout '${kv('lightlink.layout')}'`);
  const file = new basis.KTX2File(bytes);
  if (!file.isValid() || !file.isHDR() || !file.startTranscoding()) {
    fail(`${entry.ktx2}: the basis transcoder refuses it`);
    continue;
  }
  const dst = new Uint8Array(file.getImageTranscodedSizeInBytes(0, 0, 0, 25));
  if (!file.transcodeImage(dst, 0, 0, 0, 25, 0, -1, -1)) fail(`${entry.ktx2}: transcodeImage failed`);
  file.close();
  file.delete();
  const half = new Uint16Array(dst.buffer);
  if (entry.kind?.endsWith('_sh')) decodedHalf[entry.kind] = half;
  let se = 0, sv = 0;
  const w = exr.width, h = exr.height;
  for (let y = 0; y < h; y++)
    for (let x = 0; x < w; x++)
      for (let c = 0; c < 3; c++) {
        const s = exr.data[4 * ((h - 1 - y) * w + x) + c], d = DataUtils.fromHalfFloat(half[4 * (y * w + x) + c]);
        se += (d - s) ** 2;
        sv += s * s;
      }
  const relRmse = Math.sqrt(se / sv);
  // UASTC HDR 4x4 at quality 1 measured ~1 % on these maps; 5 % leaves room for encoder changes.
  if (!(relRmse < 0.05)) fail(`${entry.ktx2}: relative RMSE ${relRmse} against its EXR`);
  if (Math.abs(relRmse - entry.rel_rmse) > 1e-9) fail(`${entry.ktx2}: ktx2.json says rel RMSE ${entry.rel_rmse}, measured ${relRmse}`);
  console.log(`${entry.ktx2}: ${entry.ktx2_bytes} bytes (EXR ${entry.exr_bytes}), rel RMSE ${relRmse.toFixed(4)}`);
}

// A ratio file: UASTC LDR (basis's KTX2 has vkFormat UNDEFINED with a UASTC DFD), linear, its
// form and scale as key/values; restored with the decoded L00 it stays within 3 % of k * L00
// (measured <= 1.7 %).
function checkRatio(entry, bytes, container, exr, kv) {
  const index = exr.header['lightlink.sh_index'];
  if (container.vkFormat !== 0) fail(`${entry.ktx2}: vkFormat ${container.vkFormat}, expected UNDEFINED (UASTC LDR)`);
  if (kv('lightlink.ktx2_form') !== 'ratio_to_L00' || Math.abs(Number(kv('lightlink.ratio_scale')) - ratioScale[index]) > 1e-6)
    fail(`${entry.ktx2}: key/values form '${kv('lightlink.ktx2_form')}' scale '${kv('lightlink.ratio_scale')}'`);
  const l00 = decodedHalf[entry.kind];
  const l00Bytes = readFileSync(join(out, entry.kind === 'grid_sh' ? 'grid_L00.exr' : 'lightmap_L00.exr'));
  const l00Exr = new EXRLoader().setDataType(FloatType).parse(l00Bytes.buffer.slice(l00Bytes.byteOffset, l00Bytes.byteOffset + l00Bytes.byteLength));
  const file = new basis.KTX2File(bytes);
  if (!file.isValid() || file.isHDR() || !file.startTranscoding()) {
    fail(`${entry.ktx2}: the basis transcoder refuses it as LDR`);
    return;
  }
  const dst = new Uint8Array(file.getImageTranscodedSizeInBytes(0, 0, 0, 13));
  if (!file.transcodeImage(dst, 0, 0, 0, 13, 0, -1, -1)) fail(`${entry.ktx2}: transcodeImage failed`);
  file.close();
  file.delete();
  const w = exr.width, h = exr.height, k = ratioScale[index];
  let se = 0, sb = 0;
  for (let y = 0; y < h; y++)
    for (let x = 0; x < w; x++)
      for (let c = 0; c < 3; c++) {
        const e = 4 * ((h - 1 - y) * w + x) + c, t = 4 * (y * w + x) + c;
        const restored = (dst[t] / 127.5 - 1) * k * DataUtils.fromHalfFloat(l00[t]);
        se += (restored - exr.data[e]) ** 2;
        sb += (k * l00Exr.data[e]) ** 2;
      }
  const r = Math.sqrt(se / sb);
  if (!(r < 0.03)) fail(`${entry.ktx2}: restored RMS error ${r} of k * L00`);
  console.log(`${entry.ktx2}: ${entry.ktx2_bytes} bytes (EXR ${entry.exr_bytes}), ratio to L00: RMS error ${r.toFixed(4)} of k * L00`);
}

// Clear errors: no bake; no packages.
const noBake = spawnSync(process.execPath, [tool, work], { encoding: 'utf8' });
if (noBake.status !== 2 || !noBake.stderr.includes('irradiance.exr')) fail(`a folder without a bake: exit ${noBake.status}, '${noBake.stderr}'`);
const noModules = spawnSync(process.execPath, [tool, out], { encoding: 'utf8', env: { ...process.env, LIGHTLINK_NODE_MODULES: join(work, 'none') } });
if (noModules.status !== 3 || !noModules.stderr.includes('ktx2-encoder@0.6.0'))
  fail(`without the npm packages: exit ${noModules.status}, '${noModules.stderr}'`);

rmSync(work, { recursive: true, force: true });
if (failures > 0) {
  console.error(`${failures} failures`);
  process.exit(1);
}
