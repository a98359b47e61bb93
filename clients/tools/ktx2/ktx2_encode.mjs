#!/usr/bin/env node
// ktx2_encode: the KTX2 delivery step after `lightlink bake` (docs/outputs.md "KTX2").
//
//   node clients/tools/ktx2/ktx2_encode.mjs BAKE_DIR [--quality 0..4]
//
// Encodes each non-negative RGB EXR of a bake (irradiance.exr, direct.exr, lightmap_L00.exr,
// grid_L00.exr) to UASTC HDR 4x4 KTX2 beside it, with Binomial's basis_universal encoder
// (WASM, npm package ktx2-encoder@0.6.0: no Debian package ships a BC6H or UASTC HDR
// encoder). UASTC HDR (like ASTC HDR) holds non-negative RGB only: the signed SH coefficients
// of bands 1 and 2 and the validity files (Y) stay EXR, and ktx2.json lists them as kept.
// Each KTX2 is then decoded with the basis transcoder three.js ships (to RGBA half, what
// KTX2Loader does without ASTC HDR support) and compared with its source EXR as three.js's
// EXRLoader reads it; ktx2.json in BAKE_DIR reports per file the bytes, the encode time and
// that error.
//
// The npm packages are looked up in $LIGHTLINK_NODE_MODULES when it is set, else in
// node_modules beside this script (`npm ci` in clients/tools/ktx2), then in
// tests/node/node_modules of the source tree.
import { existsSync, readFileSync, readdirSync, writeFileSync } from 'node:fs';
import { createRequire } from 'node:module';
import { dirname, join, resolve } from 'node:path';
import { fileURLToPath, pathToFileURL } from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));

function usage(msg) {
  if (msg) console.error(`ktx2_encode: ${msg}`);
  console.error('usage: node ktx2_encode.mjs BAKE_DIR [--quality 0..4]');
  process.exit(2);
}

const args = process.argv.slice(2);
let bakeDir = null;
let quality = 1;
for (let i = 0; i < args.length; i++) {
  if (args[i] === '--quality') {
    quality = Number(args[++i]);
    if (!Number.isInteger(quality) || quality < 0 || quality > 4) usage(`--quality '${args[i]}' is not an integer 0..4`);
  } else if (bakeDir === null) {
    bakeDir = resolve(args[i]);
  } else {
    usage(`unexpected argument '${args[i]}'`);
  }
}
if (bakeDir === null) usage('no BAKE_DIR');
if (!existsSync(join(bakeDir, 'irradiance.exr')))
  usage(`${bakeDir} holds no irradiance.exr: not a bake of lightlink's EXR layout 2`);

// $LIGHTLINK_NODE_MODULES, when set, is the only place looked in.
const candidates = process.env.LIGHTLINK_NODE_MODULES ? [process.env.LIGHTLINK_NODE_MODULES]
                                                      : [join(here, 'node_modules'), join(here, '../../../tests/node/node_modules')];
const modules = candidates.find((d) => existsSync(join(d, 'ktx2-encoder/package.json')) && existsSync(join(d, 'three/package.json')));
if (!modules) {
  console.error(`ktx2_encode: the npm packages ktx2-encoder@0.6.0 and three@0.187.0 are not installed (looked in ${candidates.join(', ')}): ` +
                'run `npm ci` in clients/tools/ktx2, or set LIGHTLINK_NODE_MODULES to a node_modules that has them');
  process.exit(3);
}
const { encodeToKTX2 } = await import(pathToFileURL(join(modules, 'ktx2-encoder/dist/node/index.js')).href);
const THREE = await import(pathToFileURL(join(modules, 'three/build/three.module.js')).href);
const { EXRLoader } = await import(pathToFileURL(join(modules, 'three/examples/jsm/loaders/EXRLoader.js')).href);
// basis_transcoder.js is a CommonJS/UMD script inside an ESM package (three's "type":
// "module"), so it is evaluated as CommonJS by hand.
const basisDir = join(modules, 'three/examples/jsm/libs/basis');
const basisModule = { exports: {} };
new Function('module', 'exports', 'require', '__filename', '__dirname', readFileSync(join(basisDir, 'basis_transcoder.js'), 'utf8'))(
  basisModule, basisModule.exports, createRequire(join(basisDir, 'basis_transcoder.js')), join(basisDir, 'basis_transcoder.js'), basisDir);
const basis = await basisModule.exports({ wasmBinary: readFileSync(join(basisDir, 'basis_transcoder.wasm')) });
basis.initializeBasis();
const kRgbaHalf = 25;  // basis transcoder_texture_format cTFRGBA_HALF (KTX2Loader's TranscoderFormat.RGBA_HALF)

function readExr(path) {
  const b = readFileSync(path);
  return new EXRLoader().setDataType(THREE.FloatType).parse(b.buffer.slice(b.byteOffset, b.byteOffset + b.byteLength));
}

// RGBA half of mip 0, rows top-down (the source image's order).
function decodeKtx2(bytes) {
  const file = new basis.KTX2File(new Uint8Array(bytes));
  try {
    if (!file.isValid() || !file.isHDR()) throw new Error('not a valid UASTC HDR KTX2');
    if (!file.startTranscoding()) throw new Error('startTranscoding failed');
    const dst = new Uint8Array(file.getImageTranscodedSizeInBytes(0, 0, 0, kRgbaHalf));
    if (!file.transcodeImage(dst, 0, 0, 0, kRgbaHalf, 0, -1, -1)) throw new Error('transcodeImage failed');
    return { width: file.getWidth(), height: file.getHeight(), half: new Uint16Array(dst.buffer) };
  } finally {
    file.close();
    file.delete();
  }
}

// Error of the decoded KTX2 against its EXR over all texels and channels: relative RMSE
// (RMS error / RMS value), the 95th percentile of the per-texel relative error (error over
// the texel's largest |value|, floored at 1 % of the image's RMS value so black texels do
// not divide by ~0), the largest absolute error, and how many source values are negative.
function compare(exr, ktx) {
  const w = exr.width, h = exr.height;
  let se = 0, sv = 0, maxAbs = 0, negative = 0;
  const errs = new Float64Array(w * h), mags = new Float64Array(w * h);
  for (let y = 0; y < h; y++)
    for (let x = 0; x < w; x++) {
      const e = 4 * ((h - 1 - y) * w + x);  // EXRLoader returns rows bottom-up
      const k = 4 * (y * w + x);
      let texelErr = 0, mag = 0;
      for (let c = 0; c < 3; c++) {
        const s = exr.data[e + c], d = THREE.DataUtils.fromHalfFloat(ktx.half[k + c]);
        if (s < 0) negative++;
        se += (d - s) ** 2;
        sv += s * s;
        maxAbs = Math.max(maxAbs, Math.abs(d - s));
        texelErr = Math.max(texelErr, Math.abs(d - s));
        mag = Math.max(mag, Math.abs(s));
      }
      errs[y * w + x] = texelErr;
      mags[y * w + x] = mag;
    }
  const rms = Math.sqrt(sv / (3 * w * h));
  const rel = Array.from(errs, (err, t) => err / Math.max(mags[t], 0.01 * rms)).sort((a, b) => a - b);
  return {
    rel_rmse: rms > 0 ? Math.sqrt(se / (3 * w * h)) / rms : 0,
    p95_rel_error: rel[Math.min(rel.length - 1, Math.floor(0.95 * rel.length))],
    max_abs_error: maxAbs,
    negative_values: negative,
  };
}

// The non-negative RGB files: the L0 map, direct light and each SH set's L00.
const nonNegative = (h) => h['lightlink.kind'] === 'irradiance' || h['lightlink.kind'] === 'direct' ||
                           (h['lightlink.kind']?.endsWith('_sh') && h['lightlink.sh_index'] === 0);
const report = { tool: 'ktx2_encode', encoder: 'ktx2-encoder@0.6.0 (basis_universal UASTC HDR 4x4)', quality, files: [],
                 kept_exr: [] };
const quiet = (fn) => async (...a) => {  // the WASM encoder prints its progress to stdout
  const log = console.log;
  console.log = () => {};
  try {
    return await fn(...a);
  } finally {
    console.log = log;
  }
};
const encode = quiet(encodeToKTX2);
for (const name of readdirSync(bakeDir).filter((f) => f.endsWith('.exr')).sort()) {
  const exrPath = join(bakeDir, name);
  const exr = readExr(exrPath);
  const kind = exr.header['lightlink.kind'];
  if (exr.header['lightlink.layout'] !== 2) continue;
  if (!nonNegative(exr.header)) {
    report.kept_exr.push(name);
    continue;
  }
  const src = new Uint8Array(readFileSync(exrPath));
  const kvData = {};
  for (const [k, v] of Object.entries(exr.header)) if (k.startsWith('lightlink.')) kvData[k] = String(v);
  const t0 = performance.now();
  const ktx2 = await encode(src, { isUASTC: true, isHDR: true, imageType: 'exr', hdrQualityLevel: quality,
                                   generateMipmap: false, isKTX2File: true, kvData });
  const encodeMs = performance.now() - t0;
  const out = name.replace(/\.exr$/, '.ktx2');
  writeFileSync(join(bakeDir, out), ktx2);
  const decoded = decodeKtx2(ktx2);
  if (decoded.width !== exr.width || decoded.height !== exr.height) {
    console.error(`ktx2_encode: ${out} decodes to ${decoded.width}x${decoded.height}, its EXR is ${exr.width}x${exr.height}`);
    process.exit(1);
  }
  const err = compare(exr, decoded);
  report.files.push({ exr: name, ktx2: out, kind, width: exr.width, height: exr.height, exr_bytes: src.length,
                      ktx2_bytes: ktx2.length, encode_ms: Math.round(encodeMs), ...err });
  console.log(`${out.padEnd(22)} ${String(ktx2.length).padStart(9)} bytes (EXR ${src.length})  ` +
              `${encodeMs.toFixed(0).padStart(6)} ms  rel RMSE ${err.rel_rmse.toFixed(4)}  p95 ${err.p95_rel_error.toFixed(4)}` +
              (err.negative_values ? `  (${err.negative_values} negative source values)` : ''));
}
if (report.kept_exr.length > 0)
  console.log(`kept as EXR (signed SH coefficients or validity, which UASTC HDR cannot hold): ${report.kept_exr.join(', ')}`);
writeFileSync(join(bakeDir, 'ktx2.json'), JSON.stringify(report, null, 1) + '\n');
