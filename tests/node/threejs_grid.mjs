// three.js reads bake's grid_threejs.json + .bin into its LightProbeGrid (WebGPU) and
// LightProbeGridWebGL as a Data3DTexture, and the irradiance it evaluates for a position and
// normal matches lightlink's from grid.raw (docs/sh.md's formula, lightlink's trilinear
// grid) to float precision: at every probe and at points between probes, for several
// normals. The texture is read the way three.js's shader does (lightprobes_pars_fragment:
// sample position, clamp, atlas z mapping, trilinear filtering, the c0..c8 unpacking; the
// test checks the chunk still unpacks so) and evaluated with three's
// SphericalHarmonics3.getIrradianceAt, the CPU twin of the shader's constants.
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { execFileSync } from 'node:child_process';
import * as THREE from 'three';
import { LightProbeGridWebGL } from 'three/addons/lighting/LightProbeGridWebGL.js';
import { LightProbeGrid } from 'three/addons/lighting/LightProbeGrid.js';
import chunk from 'three/src/renderers/shaders/ShaderChunk/lightprobes_pars_fragment.glsl.js';

const fail = (msg) => { console.error(`FAIL: ${msg}`); process.exit(1); };

// The shader's unpacking, which unpack() below mirrors.
for (const line of ['vec3 c0 = s0.xyz;', 'vec3 c1 = vec3( s0.w, s1.xy );', 'vec3 c2 = vec3( s1.zw, s2.x );',
  'vec3 c3 = s2.yzw;', 'vec3 c4 = s3.xyz;', 'vec3 c5 = vec3( s3.w, s4.xy );', 'vec3 c6 = vec3( s4.zw, s5.x );',
  'vec3 c7 = s5.yzw;', 'vec3 c8 = s6.xyz;', 'float paddedSlices = nz + 2.0;', 'float uvZBase     = uvw.z * nz + 1.0;'])
  if (!chunk.includes(line)) fail(`three.js's lightprobes_pars_fragment no longer has '${line}'`);

// Bake the demo scene with a grid.
const work = fs.mkdtempSync(path.join(os.tmpdir(), 'lightlink-threejs-grid-'));
const scene = path.join(process.env.LIGHTLINK_SOURCE_DIR, 'clients/demo/cornell_box.gltf');
execFileSync(process.env.LIGHTLINK_CLI, ['bake', scene, '-o', work, '--preset', 'draft', '--grid', 'on', '-q'],
  { stdio: ['ignore', 'ignore', 'inherit'] });

// --- three.js side: what a page does with the two files (docs/outputs.md) ---
const meta = JSON.parse(fs.readFileSync(path.join(work, 'grid_threejs.json'), 'utf8'));
const bin = fs.readFileSync(path.join(work, meta.texture.data));
const data = new Float32Array(bin.buffer, bin.byteOffset, bin.byteLength / 4);
const min = new THREE.Vector3(...meta.min), max = new THREE.Vector3(...meta.max);
const size = max.clone().sub(min), center = min.clone().add(max).multiplyScalar(0.5);
const [nx, ny, nz] = meta.resolution;
const grids = [new LightProbeGridWebGL(size.x, size.y, size.z, nx, ny, nz), new LightProbeGrid(size.x, size.y, size.z, nx, ny, nz)];
const texture = new THREE.Data3DTexture(data, meta.texture.width, meta.texture.height, meta.texture.depth);
texture.format = THREE.RGBAFormat;
texture.type = THREE.FloatType;
texture.minFilter = texture.magFilter = THREE.LinearFilter;
texture.needsUpdate = true;
for (const g of grids) {
  g.position.copy(center);
  g.updateBoundingBox();
  g.texture = texture;
}
const grid = grids[0];
if (data.length !== nx * ny * 7 * (nz + 2) * 4) fail(`texture has ${data.length} floats for ${nx}x${ny}x${nz} probes`);

// GL's trilinear filter on the RGBA texture, clamp-to-edge, at normalised coordinates.
function fetch(u, v, w) {
  const { width: W, height: H, depth: D, data: d } = texture.image;
  const out = [0, 0, 0, 0];
  const axis = (t, n) => {
    const x = t * n - 0.5, i = Math.floor(x), f = x - i;
    const c = (k) => Math.min(Math.max(k, 0), n - 1);
    return [[c(i), 1 - f], [c(i + 1), f]];
  };
  for (const [z, wz] of axis(w, D)) for (const [y, wy] of axis(v, H)) for (const [x, wx] of axis(u, W)) {
    const o = ((z * H + y) * W + x) * 4, wt = wx * wy * wz;
    for (let k = 0; k < 4; ++k) out[k] += wt * d[o + k];
  }
  return out;
}

// getLightProbeGridIrradiance, step by step.
function threeIrradiance(g, worldPos, n) {
  const res = g.resolution, range = g.boundingBox.max.clone().sub(g.boundingBox.min);
  const spacing = range.clone().divide(res);
  const p = worldPos.clone().add(n.clone().multiply(spacing).multiplyScalar(0.5));
  const uvw = p.sub(g.boundingBox.min).divide(range);
  uvw.x = Math.min(Math.max(uvw.x, 0.5 / res.x), 1 - 0.5 / res.x);
  uvw.y = Math.min(Math.max(uvw.y, 0.5 / res.y), 1 - 0.5 / res.y);
  uvw.z = Math.min(Math.max(uvw.z, 0.5 / res.z), 1 - 0.5 / res.z);
  const padded = res.z + 2, depth = 7 * padded, zBase = uvw.z * res.z + 1;
  const s = [];
  for (let t = 0; t < 7; ++t) s.push(...fetch(uvw.x, uvw.y, (zBase + t * padded) / depth));
  const sh = new THREE.SphericalHarmonics3();
  for (let k = 0; k < 9; ++k) sh.coefficients[k].set(s[3 * k], s[3 * k + 1], s[3 * k + 2]);
  const e = sh.getIrradianceAt(n, new THREE.Vector3());
  return [Math.max(e.x, 0), Math.max(e.y, 0), Math.max(e.z, 0)];
}

// --- lightlink side: grid.raw (docs/outputs.md) and docs/sh.md's irradiance ---
const raw = fs.readFileSync(path.join(work, 'grid.raw'));
if (raw.toString('latin1', 0, 8) !== 'LLGRID01') fail('grid.raw has no LLGRID01 header');
const bands = raw.readUInt32LE(16), nc = bands * bands;
const dims = [raw.readUInt32LE(20), raw.readUInt32LE(24), raw.readUInt32LE(28)];
const origin = [raw.readFloatLE(32), raw.readFloatLE(36), raw.readFloatLE(40)];
const spacing = raw.readFloatLE(44);
const sh = new Float32Array(raw.buffer.slice(raw.byteOffset + 48, raw.byteOffset + 48 + dims[0] * dims[1] * dims[2] * 3 * nc * 4));
if (dims.join() !== meta.resolution.join()) fail(`grid.raw dims ${dims} vs three.js resolution ${meta.resolution}`);

function lightlinkIrradiance(worldPos, n) {
  // Trilinear over grid points origin + spacing * i, clamped to the grid.
  const L = Array.from({ length: 3 }, () => new Float64Array(9));
  const axis = (a) => {
    const x = Math.min(Math.max((worldPos.getComponent(a) - origin[a]) / spacing, 0), dims[a] - 1);
    const i = Math.min(Math.floor(x), dims[a] - 2 < 0 ? 0 : dims[a] - 2), f = x - i;
    return dims[a] === 1 ? [[0, 1]] : [[i, 1 - f], [i + 1, f]];
  };
  for (const [z, wz] of axis(2)) for (const [y, wy] of axis(1)) for (const [x, wx] of axis(0)) {
    const e = (z * dims[1] + y) * dims[0] + x, w = wx * wy * wz;
    for (let ch = 0; ch < 3; ++ch) for (let i = 0; i < Math.min(nc, 9); ++i) L[ch][i] += w * sh[e * 3 * nc + ch * nc + i];
  }
  const { x, y, z } = n;
  const Y = [0.282095, 0.488603 * y, 0.488603 * z, 0.488603 * x, 1.092548 * x * y, 1.092548 * y * z,
    0.315392 * (3 * z * z - 1), 1.092548 * x * z, 0.546274 * (x * x - y * y)];
  const A = [Math.PI, 2 * Math.PI / 3, 2 * Math.PI / 3, 2 * Math.PI / 3, Math.PI / 4, Math.PI / 4, Math.PI / 4, Math.PI / 4, Math.PI / 4];
  return L.map((c) => Math.max(0, c.reduce((s, v, i) => s + A[i] * v * Y[i], 0)));
}

// --- compare ---
const normals = [[0, 1, 0], [0, -1, 0], [1, 0, 0], [-1, 0, 0], [0, 0, 1], [0, 0, -1], [0.3, -0.8, 0.5], [-0.6, 0.2, 0.77]]
  .map((v) => new THREE.Vector3(...v).normalize());
let scale = 0;
for (let i = 0; i < sh.length; i += 3 * nc) scale = Math.max(scale, Math.abs(sh[i]));  // largest red L00
const tol = 2e-5 * scale * Math.PI;
let worst = 0, count = 0;
const check = (where, pos, n) => {
  const a = threeIrradiance(grid, pos, n), b = lightlinkIrradiance(pos.clone().add(n.clone().multiplyScalar(spacing * 0.5)), n);
  for (let ch = 0; ch < 3; ++ch) {
    const d = Math.abs(a[ch] - b[ch]);
    worst = Math.max(worst, d);
    if (!(d <= tol)) fail(`${where} normal ${n.toArray().map((v) => v.toFixed(2))}: three.js ${a} vs lightlink ${b} (tol ${tol})`);
  }
  ++count;
};
// At every probe (three.js's probe position must be lightlink's grid point), each normal
// shifted back by the half spacing three.js's shader adds, so the sample lands on the probe.
const probe = new THREE.Vector3(), probe2 = new THREE.Vector3();
for (let z = 0; z < nz; ++z) for (let y = 0; y < ny; ++y) for (let x = 0; x < nx; ++x) {
  grids[0].getProbePosition(x, y, z, probe);
  grids[1].getProbePosition(x, y, z, probe2);
  const ll = [origin[0] + spacing * x, origin[1] + spacing * y, origin[2] + spacing * z];
  if (probe.distanceTo(new THREE.Vector3(...ll)) > 1e-5 * (1 + spacing) || probe2.distanceTo(probe) > 1e-6)
    fail(`probe ${x},${y},${z}: three.js at ${probe.toArray()} (WebGPU ${probe2.toArray()}), lightlink at ${ll}`);
  const n = normals[(x + y + z) % normals.length];
  check(`probe ${x},${y},${z}`, probe.clone().sub(n.clone().multiplyScalar(spacing * 0.5)), n);
}
// Between probes: three.js's trilinear filter and lightlink's trilinear grid agree.
let seed = 1;
const rnd = () => ((seed = (seed * 16807) % 2147483647) / 2147483647);
for (let k = 0; k < 500; ++k) {
  const p = new THREE.Vector3(origin[0] + spacing * (dims[0] - 1) * rnd(), origin[1] + spacing * (dims[1] - 1) * rnd(),
    origin[2] + spacing * (dims[2] - 1) * rnd());
  const n = normals[k % normals.length];
  check(`point ${p.toArray().map((v) => v.toFixed(3))}`, p.sub(n.clone().multiplyScalar(spacing * 0.5)), n);
}
console.log(`ok: ${nx}x${ny}x${nz} probes (${bands} bands) read by three.js r${THREE.REVISION}; ${count} irradiance ` +
  `checks, largest |three.js - lightlink| ${worst.toExponential(2)} lux (tolerance ${tol.toExponential(2)}, ` +
  `largest L00 ${scale.toFixed(3)})`);
fs.rmSync(work, { recursive: true, force: true });
