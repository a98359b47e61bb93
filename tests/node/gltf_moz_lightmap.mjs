// three.js's GLTFLoader reads what the glTF writers produce, and the MOZ_lightmap binding
// works with the GLTFLoader plugin docs/outputs.md shows: on the writer's samples
// (argv[2], written by test_charts' GltfLighting test), every mesh with a lightmap uv
// (`uv1`) gets the irradiance EXR as its lightMap on channel 1 with the EXR's values, the
// others none; the samples without the map load with no lightMap at all.
import fs from 'node:fs';
import path from 'node:path';
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { EXRLoader } from 'three/addons/loaders/EXRLoader.js';

const fail = (msg) => { console.error(`FAIL: ${msg}`); process.exit(1); };
const samples = process.argv[2];
if (!samples || !fs.existsSync(samples) || !fs.readdirSync(samples).some((f) => f.endsWith('_bound.gltf'))) {
  console.log(`SKIP: no glTF samples in '${samples}' (shared scenes absent?)`);
  process.exit(77);
}
// FileLoader reports progress with the DOM's ProgressEvent, which node lacks.
globalThis.ProgressEvent ??= class extends Event {
  constructor(type, init) { super(type); Object.assign(this, init); }
};

// The plugin of docs/outputs.md; `loadExr(uri)` resolves to EXRLoader's texture (in a page:
// (uri) => new EXRLoader().loadAsync(new URL(uri, gltfUrl).href)).
class MozLightmapPlugin {
  constructor(parser, loadExr) { this.parser = parser; this.loadExr = loadExr; this.name = 'MOZ_lightmap'; }
  async extendMaterialParams(materialIndex, params) {
    const ext = this.parser.json.materials[materialIndex].extensions?.MOZ_lightmap;
    if (!ext) return;
    const texture = this.parser.json.textures[ext.index];
    const image = this.parser.json.images[texture.extensions.LIGHTLINK_texture_exr.source];
    const map = await this.loadExr(image.uri);
    map.channel = ext.texCoord ?? 0;  // 1: the uv1 attribute, TEXCOORD_1
    params.lightMap = map;
    params.lightMapIntensity = ext.intensity ?? 1;
  }
}

const bytes = (f) => { const b = fs.readFileSync(f); return b.buffer.slice(b.byteOffset, b.byteOffset + b.byteLength); };
function loadExr(uri) {
  const d = new EXRLoader().parse(bytes(path.join(samples, decodeURIComponent(uri))));
  const t = new THREE.DataTexture(d.data, d.width, d.height, d.format, d.type);
  t.needsUpdate = true;
  return Promise.resolve(t);
}

async function load(file) {
  const json = JSON.parse(fs.readFileSync(file, 'utf8'));
  // Buffers inline, so FileLoader needs no file:// fetch (which node lacks).
  for (const b of json.buffers ?? [])
    if (b.uri && !b.uri.startsWith('data:'))
      b.uri = 'data:application/octet-stream;base64,' + fs.readFileSync(path.join(path.dirname(file), b.uri)).toString('base64');
  // The source scene's own textures (PNG/JPEG, which node cannot decode) are not needed here.
  for (const m of json.materials ?? []) {
    for (const k of ['normalTexture', 'occlusionTexture', 'emissiveTexture']) delete m[k];
    for (const k of ['baseColorTexture', 'metallicRoughnessTexture']) delete m.pbrMetallicRoughness?.[k];
  }
  const loader = new GLTFLoader();
  loader.register((parser) => new MozLightmapPlugin(parser, loadExr));
  return loader.parseAsync(JSON.stringify(json), '');
}

let checked = 0;
for (const name of fs.readdirSync(samples).filter((f) => /_(un)?bound\.gltf$/.test(f)).sort()) {
  const bound = name.endsWith('_bound.gltf');
  const gltf = await load(path.join(samples, name));
  let lit = 0, unlit = 0;
  gltf.scene.traverse((o) => {
    if (!o.isMesh) return;
    const hasUv1 = o.geometry.attributes.uv1 !== undefined;
    const map = o.material.lightMap;
    if (!bound || !hasUv1) {
      if (map) fail(`${name}: mesh '${o.name}' got a lightMap without ${bound ? 'a lightmap uv' : 'irradiance.exr'}`);
      ++unlit;
      return;
    }
    if (!map) fail(`${name}: mesh '${o.name}' has a lightmap uv but no lightMap`);
    if (map.channel !== 1) fail(`${name}: lightMap channel ${map.channel}, want 1`);
    // The sample map is RGB (1, 0.5, 0.25) everywhere; EXRLoader gives RGBA half floats.
    const px = Array.from(map.image.data.slice(0, 4), (h) => map.type === THREE.HalfFloatType ? THREE.DataUtils.fromHalfFloat(h) : h);
    if (Math.abs(px[0] - 1) > 1e-3 || Math.abs(px[1] - 0.5) > 1e-3 || Math.abs(px[2] - 0.25) > 1e-3)
      fail(`${name}: lightMap texel ${px}, want 1, 0.5, 0.25`);
    ++lit;
  });
  if (bound && lit === 0) fail(`${name}: no mesh got the lightMap`);
  console.log(`ok   ${name}: ${lit} meshes lightmapped, ${unlit} without`);
  ++checked;
}
console.log(`${checked} samples loaded by three.js r${THREE.REVISION}'s GLTFLoader`);
