// lightlink's browser viewer (docs/web.md): loads a bake folder given as ?bake=..., draws
// its *_lm.gltf lit by the bake's lightmaps and grid with the same shading, exposure and tone
// mapping as `lightlink render`, and redraws on orbit. `document.body.dataset.state` becomes
// `ready` (or `error`, with the message in dataset.error) for scripts such as the tests.
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { readParams } from './params.js';
import { fetchFile } from './fetch_file.js';
import { loadBakeLighting } from './bake_lighting.js';
import { applyLightlinkMaterials } from './materials.js';
import { makeCamera } from './camera.js';
import { autoExposure, makeTonemapPass } from './tonemap.js';
import { startLive } from './live.js';

const status = document.getElementById('status');
const say = (text) => { status.textContent = text; };

// The glTF's name: ?gltf=..., else the *_lm.gltf (or .glb) that report.json lists.
async function gltfName(params) {
  if (params.gltf) return params.gltf;
  const report = await fetchFile(new URL('report.json', params.bakeUrl).href, 'json');
  const name = (report.outputs ?? []).find((f) => /_lm\.(gltf|glb)$/.test(f));
  if (!name) throw new Error(`${params.bakeUrl}report.json lists no *_lm.gltf: give the glTF as ?gltf=NAME`);
  return name;
}

async function start() {
  const params = readParams(location.search);
  if (!params.ui) document.body.classList.add('plain');
  const gltfUrl = new URL(await gltfName(params), params.bakeUrl).href;
  say(`loading ${gltfUrl}`);
  const gltf = await new GLTFLoader().loadAsync(gltfUrl).catch((e) => { throw new Error(`cannot load ${gltfUrl}: ${e.message}`); });
  const lighting = await loadBakeLighting(gltf.parser.json.extensions?.LIGHTLINK_lighting, gltfUrl);
  const materials = applyLightlinkMaterials(gltf.scene, lighting);
  const { counts } = materials;

  const canvas = document.getElementById('view');
  // No multisampling and one device pixel per pixel when a size is given: render samples each
  // pixel once at its centre, and the tests compare the two pixel by pixel.
  const renderer = new THREE.WebGLRenderer({ canvas, antialias: false, preserveDrawingBuffer: true });
  renderer.setPixelRatio(params.size ? 1 : devicePixelRatio);
  const size = params.size ?? { width: innerWidth, height: innerHeight };
  renderer.setSize(size.width, size.height, !params.size);
  const bounds = new THREE.Box3().setFromObject(gltf.scene);
  const { camera, target: lookAt } = makeCamera(params, bounds, size.width / size.height);
  const scene = new THREE.Scene();
  scene.add(gltf.scene);

  const buffer = renderer.getDrawingBufferSize(new THREE.Vector2());
  let target = new THREE.WebGLRenderTarget(buffer.x, buffer.y, { type: THREE.FloatType, depthBuffer: true });
  const tonemap = makeTonemapPass();
  let exposure = params.exposure;
  let frameMs = 0;
  const draw = (measureExposure) => {
    const t0 = performance.now();
    renderer.setRenderTarget(target);
    renderer.setClearColor(0x000000, 0);
    renderer.clear();
    renderer.render(scene, camera);
    if (measureExposure && params.exposure === 0) {  // auto: from this frame's radiance
      const pixels = new Float32Array(4 * target.width * target.height);
      renderer.readRenderTargetPixels(target, 0, 0, target.width, target.height, pixels);
      exposure = autoExposure(pixels);
    }
    tonemap.draw(renderer, target, exposure);
    frameMs = performance.now() - t0;
  };
  draw(true);

  // Orbit for people: drawn at the exposure of the last settled view, measured again on release.
  const controls = new OrbitControls(camera, canvas);
  controls.target.copy(lookAt);
  controls.update();
  controls.addEventListener('change', () => draw(false));
  controls.addEventListener('end', () => draw(true));
  addEventListener('resize', () => {
    if (params.size) return;
    renderer.setSize(innerWidth, innerHeight);
    camera.aspect = innerWidth / innerHeight;
    camera.updateProjectionMatrix();
    const b = renderer.getDrawingBufferSize(new THREE.Vector2());
    target.dispose();
    target = new THREE.WebGLRenderTarget(b.x, b.y, { type: THREE.FloatType, depthBuffer: true });
    draw(true);
  });

  const encoding = lighting.bands === 0 ? 'L0 irradiance.exr' : `L${lighting.bands - 1} SH (${lighting.bands * lighting.bands} coefficients)`;
  say(`${counts.lightmapped} meshes from the lightmap (${encoding}), ${counts.gridLit} from the ` +
      `${lighting.grid ? 'grid' : '(absent) grid'}; exposure ${exposure.toPrecision(4)}; frame ${frameMs.toFixed(1)} ms`);
  // Frame time for benchmarks (bench/web): n redraws, each waited for by a one-pixel read.
  const measureFrames = (n) => {
    const one = new Float32Array(4);
    const t0 = performance.now();
    for (let i = 0; i < n; ++i) {
      draw(false);
      renderer.setRenderTarget(target);
      renderer.readRenderTargetPixels(target, 0, 0, 1, 1, one);
      renderer.setRenderTarget(null);
    }
    return (performance.now() - t0) / n;
  };
  window.lightlinkViewer = { counts, exposure, frameMs, bands: lighting.bands, measureFrames };
  if (params.live) {
    say('live: opening the bake on the daemon');
    window.lightlinkViewer.live = await startLive({ params, gltf, scene, camera, canvas, orbit: controls, materials, draw, say });
  }
  document.body.dataset.state = 'ready';
}

start().catch((e) => {
  say(`error: ${e.message}`);
  status.classList.add('error');
  document.body.dataset.error = e.message;
  document.body.dataset.state = 'error';
  console.error(e);
});
