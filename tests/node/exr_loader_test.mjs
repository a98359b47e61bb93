// three.js's EXRLoader reads every EXR `lightlink bake` writes, for each encoding, and what
// it decodes equals what OpenEXR reads from the same file (exr_dump, argv[2]): the same size
// and values (rows bottom-up, as EXRLoader returns them), the lightlink.* header attributes.
// The grid files are also held against grid.raw, lightlink's float32 form of the same SH.
// Usage: node exr_loader_test.mjs EXR_DUMP   (LIGHTLINK_CLI, LIGHTLINK_SOURCE_DIR from ctest)
import { execFileSync } from 'node:child_process';
import { mkdtempSync, readFileSync, readdirSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { FloatType } from 'three';
import { EXRLoader } from 'three/examples/jsm/loaders/EXRLoader.js';

const exrDump = process.argv[2];
const cli = process.env.LIGHTLINK_CLI;
const source = process.env.LIGHTLINK_SOURCE_DIR;
if (!exrDump || !cli || !source) {
  console.error('usage: LIGHTLINK_CLI=... LIGHTLINK_SOURCE_DIR=... node exr_loader_test.mjs EXR_DUMP');
  process.exit(2);
}
const demo = join(source, 'clients/demo/cornell_box.gltf');
const work = mkdtempSync(join(tmpdir(), 'lightlink-exr-'));
let failures = 0;
const fail = (msg) => {
  console.error('FAIL ' + msg);
  failures++;
};

function loadWithThree(path) {
  const bytes = readFileSync(path);
  const loader = new EXRLoader().setDataType(FloatType);
  return loader.parse(bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength));
}

function dumpWithOpenExr(path) {
  const bin = path + '.bin';
  const meta = JSON.parse(execFileSync(exrDump, [path, bin], { encoding: 'utf8' }));
  const b = readFileSync(bin);
  meta.values = new Float32Array(b.buffer.slice(b.byteOffset, b.byteOffset + b.byteLength));
  return meta;
}

// Checks one file; returns three's decode (RGBA float, rows bottom-up).
function checkFile(dir, name, encoding) {
  const path = join(dir, name);
  let tex;
  try {
    tex = loadWithThree(path);
  } catch (e) {
    fail(`${encoding}/${name}: EXRLoader refused it: ${e.message}`);
    return null;
  }
  const ref = dumpWithOpenExr(path);
  if (tex.width !== ref.width || tex.height !== ref.height) {
    fail(`${encoding}/${name}: EXRLoader ${tex.width}x${tex.height}, OpenEXR ${ref.width}x${ref.height}`);
    return null;
  }
  const rgb = ref.channels.length === 3;
  if (!(rgb && ref.channels.join() === 'B,G,R') && !(ref.channels.length === 1 && ref.channels[0] === 'Y'))
    fail(`${encoding}/${name}: channels ${ref.channels} are not plain R,G,B or Y`);
  for (const [k, v] of Object.entries(ref.attributes))
    if (tex.header[k] !== v) fail(`${encoding}/${name}: header ${k} is ${tex.header[k]} in three.js, ${v} in OpenEXR`);
  if (tex.header['lightlink.layout'] !== 2) fail(`${encoding}/${name}: lightlink.layout ${tex.header['lightlink.layout']}`);
  if (tex.header['lightlink.encoding'] !== encoding) fail(`${encoding}/${name}: lightlink.encoding ${tex.header['lightlink.encoding']}`);
  // OpenEXR's channels are in file order (alphabetical: B, G, R); three's output is RGBA.
  const order = rgb ? [2, 1, 0] : [0, 0, 0];
  const w = ref.width, h = ref.height, nc = ref.channels.length;
  let mismatches = 0, nonzero = 0;
  for (let y = 0; y < h; y++)
    for (let x = 0; x < w; x++) {
      const t = (h - 1 - y) * w + x;  // EXRLoader: the file's row y is data row h-1-y
      for (let c = 0; c < 3; c++) {
        const want = ref.values[(y * w + x) * nc + order[c]];
        const got = tex.data[4 * t + c];
        if (want !== 0) nonzero++;
        if (got !== want && mismatches++ < 3) fail(`${encoding}/${name}: texel (${x}, ${y}) channel ${c}: three ${got}, OpenEXR ${want}`);
      }
      if (tex.data[4 * t + 3] !== 1) mismatches++;
    }
  if (mismatches > 0) fail(`${encoding}/${name}: ${mismatches} values differ`);
  if (nonzero === 0 && !name.startsWith('lightmap_L2') && !name.startsWith('grid_L2')) fail(`${encoding}/${name}: all zero`);
  return { tex, ref };
}

// grid_<c>.exr against grid.raw: header 48 bytes, float32 SH per point (R coeffs, G, B), validity.
function checkGridAgainstRaw(dir, encoding, decoded) {
  const raw = readFileSync(join(dir, 'grid.raw'));
  const dv = new DataView(raw.buffer, raw.byteOffset, raw.byteLength);
  const bands = dv.getUint32(16, true);
  const dims = [dv.getUint32(20, true), dv.getUint32(24, true), dv.getUint32(28, true)];
  const nc = bands * bands;
  const expectedBands = { l0: 1, l1: 2, l2: 3 }[encoding];
  if (bands !== expectedBands) fail(`${encoding}/grid.raw: ${bands} bands, expected ${expectedBands}`);
  const meta = JSON.parse(readFileSync(join(dir, 'grid.json'), 'utf8'));
  if (meta.sh_files.length !== nc) fail(`${encoding}/grid.json: ${meta.sh_files.length} sh_files for ${nc} coefficients`);
  const points = dims[0] * dims[1] * dims[2];
  let worst = 0;
  for (let i = 0; i < nc; i++) {
    const file = meta.sh_files[i];
    const d = decoded[file];
    if (!d) {
      fail(`${encoding}: ${file} named by grid.json was not written`);
      continue;
    }
    const { tex } = d;
    const half = d.ref.half;
    for (let p = 0; p < points; p++) {
      const x = p % dims[0], y = Math.floor(p / dims[0]) % dims[1], z = Math.floor(p / (dims[0] * dims[1]));
      const px = z * dims[0] + x, row = tex.height - 1 - y;
      for (let c = 0; c < 3; c++) {
        const want = dv.getFloat32(48 + 4 * (p * 3 * nc + c * nc + i), true);
        const got = tex.data[4 * (row * tex.width + px) + c];
        const err = Math.abs(got - want) / (Math.abs(want) + 1e-4);
        worst = Math.max(worst, err);
        if (!half && got !== want) {
          fail(`${encoding}/${file}: point ${p} channel ${c}: ${got} vs grid.raw ${want}`);
          return;
        }
      }
    }
  }
  if (worst > 1e-3) fail(`${encoding}: grid EXR vs grid.raw relative error ${worst} beyond half rounding`);
  return worst;
}

const cache = join(work, 'cache');
// Draft has no finer direct layer; medium (direct scale 2) adds direct_valid.exr and an
// irradiance.exr at the direct layer's size.
const runs = [['l0', ['--preset', 'draft']], ['l1', ['--preset', 'draft']], ['l2', ['--preset', 'draft']],
              ['l2', ['--preset', 'draft', '--float']], ['l1', ['--preset', 'medium']]];
for (const [encoding, extra] of runs) {
  const out = join(work, encoding + extra.join(''));
  execFileSync(cli, ['bake', demo, '-o', out, '--encoding', encoding, '--cache-dir', cache, '-q', ...extra],
               { stdio: 'inherit' });
  const report = JSON.parse(readFileSync(join(out, 'report.json'), 'utf8'));
  const exrs = readdirSync(out).filter((f) => f.endsWith('.exr')).sort();
  const listed = report.outputs.filter((f) => f.endsWith('.exr')).sort();
  if (exrs.join() !== listed.join()) fail(`${encoding}: report lists ${listed}, the folder holds ${exrs}`);
  if (!exrs.includes('irradiance.exr')) fail(`${encoding}: no irradiance.exr`);
  if (extra.includes('medium') && !exrs.includes('direct_valid.exr')) fail(`${encoding} medium: no direct_valid.exr`);
  const want = { l0: 0, l1: 4, l2: 9 }[encoding];
  const sh = exrs.filter((f) => f.startsWith('lightmap_L'));
  if (sh.length !== want) fail(`${encoding}: ${sh.length} lightmap SH files, expected ${want}`);
  const decoded = {};
  for (const f of exrs) {
    const d = checkFile(out, f, encoding);
    if (d) decoded[f] = d;
  }
  const worst = checkGridAgainstRaw(out, encoding, decoded);
  console.log(`${encoding}${extra.join('')}: EXRLoader read ${exrs.length} EXRs equal to OpenEXR's decode; grid vs grid.raw worst relative error ${worst?.toExponential(2)}`);
}
rmSync(work, { recursive: true, force: true });
if (failures > 0) {
  console.error(`${failures} failures`);
  process.exit(1);
}
