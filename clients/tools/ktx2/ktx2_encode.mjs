#!/usr/bin/env node
// ktx2_encode: the KTX2 delivery step after `lightlink bake` (docs/outputs.md "KTX2").
//
//   node clients/tools/ktx2/ktx2_encode.mjs BAKE_DIR [--quality 0..4]
//
// Encodes each non-negative RGB EXR of a bake (irradiance.exr, direct.exr, lightmap_L00.exr,
// grid_L00.exr) to UASTC HDR 4x4 KTX2 beside it, with Binomial's basis_universal encoder
// (WASM, npm package ktx2-encoder@0.6.0: no Debian package ships a BC6H or UASTC HDR
// encoder). UASTC HDR (like ASTC HDR) holds non-negative RGB only, so the signed SH
// coefficients of bands 1 and 2 go as their ratio to L00 (docs/outputs.md "KTX2"): for a
// non-negative radiance |L_i| <= k_i L00 with k_i = max|Y_i| / Y00, so r = L_i / (k_i L00) lies
// in [-1, 1] and (r + 1) / 2 is stored in UASTC LDR 4x4 (linear, 8 bits); an engine restores
// L_i = (2 t - 1) k_i L00 with the L00 it decoded. Validity files (Y) and band 3 stay EXR,
// and ktx2.json lists them as kept. Each KTX2 is then decoded with the basis transcoder
// three.js ships (RGBA half for HDR, what KTX2Loader does without ASTC HDR support; RGBA8 for
// the ratios) and compared with its source EXR as three.js's EXRLoader reads it (a ratio
// file through the decoded L00, as an engine would); ktx2.json in BAKE_DIR reports per file
// the bytes, the encode time and that error.
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
const kRgba32 = 13;    // cTFRGBA32: 8 bits per channel
// k_i = max over the sphere of |Y_i| / Y00 (docs/sh.md's real SH, index order l^2 + l + m).
export const RATIO_SCALE = [1, 1.7320508, 1.7320508, 1.7320508, 1.9364917, 1.9364917, 2.2360680, 1.9364917, 1.9364917];

function readExr(path) {
  const b = readFileSync(path);
  return new EXRLoader().setDataType(THREE.FloatType).parse(b.buffer.slice(b.byteOffset, b.byteOffset + b.byteLength));
}

// Mip 0 as RGBA half (HDR) or RGBA8 (LDR), rows top-down (the source image's order).
function decodeKtx2(bytes, hdr = true) {
  const file = new basis.KTX2File(new Uint8Array(bytes));
  try {
    if (!file.isValid() || file.isHDR() !== hdr) throw new Error(`not a valid UASTC ${hdr ? 'HDR' : 'LDR'} KTX2`);
    if (!file.startTranscoding()) throw new Error('startTranscoding failed');
    const format = hdr ? kRgbaHalf : kRgba32;
    const dst = new Uint8Array(file.getImageTranscodedSizeInBytes(0, 0, 0, format));
    if (!file.transcodeImage(dst, 0, 0, 0, format, 0, -1, -1)) throw new Error('transcodeImage failed');
    return { width: file.getWidth(), height: file.getHeight(), half: hdr ? new Uint16Array(dst.buffer) : null, rgba8: hdr ? null : dst };
  } finally {
    file.close();
    file.delete();
  }
}

// A signed coefficient as (r + 1) / 2 in RGBA8, rows top-down; r = L_i / (k_i L00) per channel,
// 0 where L00 is not positive.
function ratioImage(coeff, l00, scale) {
  const w = coeff.width, h = coeff.height, rgba = new Uint8Array(4 * w * h);
  for (let y = 0; y < h; y++)
    for (let x = 0; x < w; x++) {
      const e = 4 * ((h - 1 - y) * w + x), o = 4 * (y * w + x);
      for (let c = 0; c < 3; c++) {
        const base = scale * l00.data[e + c];
        const r = base > 0 ? Math.max(-1, Math.min(1, coeff.data[e + c] / base)) : 0;
        rgba[o + c] = Math.round((r + 1) * 127.5);
      }
      rgba[o + 3] = 255;
    }
  return rgba;
}

// Error of a decoded ratio file: the coefficient restored with the decoded L00 (half, top-down)
// against the EXR's; relative RMSE, and the RMS error over the RMS of k_i L00 (how much of the
// largest possible coefficient is off).
function compareRatio(exr, l00Exr, ratio, l00Half, scale) {
  const w = exr.width, h = exr.height;
  let se = 0, sv = 0, sb = 0, maxAbs = 0;
  for (let y = 0; y < h; y++)
    for (let x = 0; x < w; x++) {
      const e = 4 * ((h - 1 - y) * w + x), k = 4 * (y * w + x);
      for (let c = 0; c < 3; c++) {
        const s = exr.data[e + c];
        const d = (ratio.rgba8[k + c] / 127.5 - 1) * scale * THREE.DataUtils.fromHalfFloat(l00Half[k + c]);
        se += (d - s) ** 2;
        sv += s * s;
        sb += (scale * l00Exr.data[e + c]) ** 2;
        maxAbs = Math.max(maxAbs, Math.abs(d - s));
      }
    }
  return { rel_rmse: sv > 0 ? Math.sqrt(se / sv) : 0, rmse_over_bound: sb > 0 ? Math.sqrt(se / sb) : 0, max_abs_error: maxAbs };
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
const report = { tool: 'ktx2_encode', encoder: 'ktx2-encoder@0.6.0 (basis_universal UASTC HDR 4x4; UASTC LDR 4x4 for ratios)', quality, files: [],
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
const names = readdirSync(bakeDir).filter((f) => f.endsWith('.exr')).sort();
const ratios = [];  // signed coefficients, encoded once their set's L00 KTX2 exists
const sets = {};    // kind -> the L00 and the restored coefficients, for the irradiance error
const decodedL00 = {};  // kind -> decoded L00 KTX2 (half), what an engine restores with
for (const name of names) {
  const exrPath = join(bakeDir, name);
  const exr = readExr(exrPath);
  const kind = exr.header['lightlink.kind'];
  if (exr.header['lightlink.layout'] !== 2) continue;
  const index = exr.header['lightlink.sh_index'];
  if (kind?.endsWith('_sh') && index >= 1 && index <= 8) {
    ratios.push({ name, exr, kind, index });
    continue;
  }
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
  if (kind?.endsWith('_sh')) decodedL00[kind] = { exr, half: decoded.half };
  report.files.push({ exr: name, ktx2: out, kind, form: 'hdr', width: exr.width, height: exr.height, exr_bytes: src.length,
                      ktx2_bytes: ktx2.length, encode_ms: Math.round(encodeMs), ...err });
  console.log(`${out.padEnd(22)} ${String(ktx2.length).padStart(9)} bytes (EXR ${src.length})  ` +
              `${encodeMs.toFixed(0).padStart(6)} ms  rel RMSE ${err.rel_rmse.toFixed(4)}  p95 ${err.p95_rel_error.toFixed(4)}` +
              (err.negative_values ? `  (${err.negative_values} negative source values)` : ''));
}
for (const { name, exr, kind, index } of ratios) {
  const l00 = decodedL00[kind];
  if (!l00) {  // no L00 of this set was encoded: the coefficient cannot be restored
    report.kept_exr.push(name);
    continue;
  }
  const scale = RATIO_SCALE[index];
  const rgba = ratioImage(exr, l00.exr, scale);
  const kvData = {};
  for (const [k, v] of Object.entries(exr.header)) if (k.startsWith('lightlink.')) kvData[k] = String(v);
  Object.assign(kvData, { 'lightlink.ktx2_form': 'ratio_to_L00', 'lightlink.ratio_scale': String(scale),
                          'lightlink.ratio_of': kind === 'grid_sh' ? 'grid_L00' : 'lightmap_L00' });
  const t0 = performance.now();
  const ktx2 = await encode(rgba, { isUASTC: true, isHDR: false, generateMipmap: false, isKTX2File: true,
                                    isSetKTX2SRGBTransferFunc: false, kvData,
                                    imageDecoder: async () => ({ width: exr.width, height: exr.height, data: rgba }) });
  const encodeMs = performance.now() - t0;
  const out = name.replace(/\.exr$/, '.ktx2');
  writeFileSync(join(bakeDir, out), ktx2);
  const decoded = decodeKtx2(ktx2, false);
  if (decoded.width !== exr.width || decoded.height !== exr.height) {
    console.error(`ktx2_encode: ${out} decodes to ${decoded.width}x${decoded.height}, its EXR is ${exr.width}x${exr.height}`);
    process.exit(1);
  }
  const err = compareRatio(exr, l00.exr, decoded, l00.half, scale);
  (sets[kind] ??= { l00, coeffs: {} }).coeffs[index] = { exr, ratio: decoded, scale };
  const exrBytes = readFileSync(join(bakeDir, name)).length;
  report.files.push({ exr: name, ktx2: out, kind, form: 'ratio_to_L00', ratio_scale: scale, width: exr.width, height: exr.height,
                      exr_bytes: exrBytes, ktx2_bytes: ktx2.length, encode_ms: Math.round(encodeMs), ...err });
  console.log(`${out.padEnd(22)} ${String(ktx2.length).padStart(9)} bytes (EXR ${exrBytes})  ` +
              `${encodeMs.toFixed(0).padStart(6)} ms  rel RMSE ${err.rel_rmse.toFixed(4)}  of k*L00 ${err.rmse_over_bound.toFixed(4)}  (ratio to L00, LDR)`);
}
// Per SH set: the irradiance E(n) = sum_i A_l L_i Y_i(n) (docs/sh.md) at the six axis normals of
// every texel, from the KTX2s (as an engine restores them) against the EXRs.
const Y = (n) => [0.282095, 0.488603 * n[1], 0.488603 * n[2], 0.488603 * n[0], 1.092548 * n[0] * n[1], 1.092548 * n[1] * n[2],
                  0.315392 * (3 * n[2] * n[2] - 1), 1.092548 * n[0] * n[2], 0.546274 * (n[0] * n[0] - n[1] * n[1])];
const A = [Math.PI, 2.094395, 2.094395, 2.094395, 0.785398, 0.785398, 0.785398, 0.785398, 0.785398];
report.irradiance = {};
for (const [kind, set] of Object.entries(sets)) {
  const idx = [0, ...Object.keys(set.coeffs).map(Number)].sort((a, b) => a - b);
  const w = set.l00.exr.width, h = set.l00.exr.height;
  const normals = [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]].map(Y);
  const errs = [], vals = [];
  for (let y = 0; y < h; y++)
    for (let x = 0; x < w; x++) {
      const e = 4 * ((h - 1 - y) * w + x), k = 4 * (y * w + x);
      for (let c = 0; c < 3; c++) {
        const l00k = THREE.DataUtils.fromHalfFloat(set.l00.half[k + c]);
        const ref = idx.map((i) => (i === 0 ? set.l00.exr : set.coeffs[i].exr).data[e + c]);
        const got = idx.map((i) => (i === 0 ? l00k : (set.coeffs[i].ratio.rgba8[k + c] / 127.5 - 1) * set.coeffs[i].scale * l00k));
        for (const yn of normals) {
          let er = 0, eg = 0;
          idx.forEach((i, j) => { er += A[i] * ref[j] * yn[i]; eg += A[i] * got[j] * yn[i]; });
          er = Math.max(er, 0);
          eg = Math.max(eg, 0);
          if (er > 0 || eg > 0) { errs.push(Math.abs(eg - er)); vals.push(er); }
        }
      }
    }
  const rms = Math.sqrt(vals.reduce((a, v) => a + v * v, 0) / Math.max(1, vals.length));
  const rel = errs.map((d, i) => d / Math.max(vals[i], 0.01 * rms)).sort((a, b) => a - b);
  const r = { rel_rmse: rms > 0 ? Math.sqrt(errs.reduce((a, d) => a + d * d, 0) / errs.length) / rms : 0,
              p95_rel_error: rel[Math.min(rel.length - 1, Math.floor(0.95 * rel.length))] ?? 0, bands: idx.length === 9 ? 3 : 2 };
  report.irradiance[kind] = r;
  console.log(`${kind}: irradiance from the KTX2s at six normals per texel: rel RMSE ${r.rel_rmse.toFixed(4)}, p95 ${r.p95_rel_error.toFixed(4)}`);
}
if (report.kept_exr.length > 0)
  console.log(`kept as EXR (validity, band 3): ${report.kept_exr.join(', ')}`);
writeFileSync(join(bakeDir, 'ktx2.json'), JSON.stringify(report, null, 1) + '\n');
