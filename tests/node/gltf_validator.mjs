// Every glTF lightlink writes passes the Khronos glTF validator with 0 errors, for every
// shared scene: `lightlink unwrap -o` of each (both writers: the edited glTF and the one
// made from an OBJ), `lightlink bake --preset draft --grid on` of the small ones (the glTF
// with its LIGHTLINK_lighting description; the five game levels and zdm2 are unwrapped
// only, to keep the run short), and the writer's samples with the irradiance map bound
// through MOZ_lightmap (argv[2], written by test_charts' GltfLighting test). External
// files (buffers, images) are read from each output's folder. Warnings and infos are
// printed by code; docs/outputs.md says which remain and why.
// Exit 77 (skipped) without ../shared/scenes.
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { execFileSync } from 'node:child_process';
import validator from 'gltf-validator';

const cli = process.env.LIGHTLINK_CLI;
const shared = process.env.LIGHTLINK_SHARED_SCENES;
const samples = process.argv[2];
if (!shared || !fs.existsSync(shared)) {
  console.log(`SKIP: shared scenes not found at '${shared}'`);
  process.exit(77);
}

// folder/file as the shared README names them; bake: small enough to bake in a second or two.
const scenes = [
  ['cornell_box_original_gltf/CornellBox-Original.gltf', true],
  ['cornell_box_vinc3r_lightmapuv/cornellBox-2.80-Eevee-gltf.gltf', true],
  ['khronos_EmissiveStrengthTest/EmissiveStrengthTest.gltf', true],
  ['khronos_LightsPunctualLamp/LightsPunctualLamp.gltf', true],
  ['khronos_MultiUVTest/MultiUVTest.gltf', true],
  ['revelry_ShadowsDirectional/shadows-directional.gltf', true],
  ['revelry_ShadowsSpot/shadows-spot.gltf', true],
  ['sauerbraten_zdm2_level_gltf/zdm2.glb', false],
  ...['Original', 'Sphere', 'Water', 'Glossy', 'Mirror', 'Empty-CO', 'Empty-RG', 'Empty-Squashed', 'Empty-White'].map(
    (v) => [`cornell_box_mcguire_obj/CornellBox-${v}.obj`, true]),
  ['redeclipse_cyanide_obj/cyanide.obj', false],
  ['redeclipse_institute_obj/institute.obj', false],
  ['tesseract_steelribs_obj/steelribs.obj', false],
  ['sauerbraten_memento_obj/memento.obj', false],
  ['sauerbraten_forge_obj/forge.obj', false],
];

const work = fs.mkdtempSync(path.join(os.tmpdir(), 'lightlink-gltf-validator-'));
const written = [];  // glTF files to validate
const run = (args) => execFileSync(cli, args, { stdio: ['ignore', 'ignore', 'pipe'] });
const isGltf = (f) => /\.(gltf|glb)$/i.test(f);

for (const [scene, bake] of scenes) {
  const input = path.join(shared, scene);
  const name = scene.replace(/[/.]/g, '_');
  const ext = input.endsWith('.glb') ? '.glb' : '.gltf';
  const unwrapDir = path.join(work, 'unwrap', name);
  fs.mkdirSync(unwrapDir, { recursive: true });
  run(['unwrap', input, '-o', path.join(unwrapDir, `out${ext}`)]);
  written.push(path.join(unwrapDir, `out${ext}`));
  if (bake) {
    const bakeDir = path.join(work, 'bake', name);
    run(['bake', input, '-o', bakeDir, '--preset', 'draft', '--grid', 'on', '-q']);
    const lm = fs.readdirSync(bakeDir).filter(isGltf);
    if (lm.length !== 1) throw new Error(`bake of ${scene} wrote ${lm.length} glTF files`);
    written.push(path.join(bakeDir, lm[0]));
  }
}
if (samples && fs.existsSync(samples))
  for (const f of fs.readdirSync(samples).filter(isGltf).sort()) written.push(path.join(samples, f));

let failed = 0;
const remaining = new Map();  // severity code -> count of files
const severity = ['error', 'warning', 'info', 'hint'];
for (const file of written) {
  const report = await validator.validateBytes(new Uint8Array(fs.readFileSync(file)), {
    uri: path.basename(file),
    maxIssues: 0,
    externalResourceFunction: (uri) =>
      new Promise((resolve, reject) => {
        try {
          resolve(new Uint8Array(fs.readFileSync(path.resolve(path.dirname(file), decodeURIComponent(uri)))));
        } catch (e) {
          reject(e.toString());
        }
      }),
  });
  const { numErrors, numWarnings, numInfos } = report.issues;
  const rel = path.relative(work, file).startsWith('..') ? file : path.relative(work, file);
  console.log(`${numErrors ? 'FAIL' : 'ok  '} ${rel}: ${numErrors} errors, ${numWarnings} warnings, ${numInfos} infos`);
  const codes = new Set();
  for (const m of report.issues.messages) {
    if (m.severity === 0) console.log(`       error ${m.code} at ${m.pointer}: ${m.message}`);
    codes.add(`${severity[m.severity]} ${m.code}`);
  }
  for (const c of codes) remaining.set(c, (remaining.get(c) || 0) + 1);
  if (numErrors) ++failed;
}
console.log(`\n${written.length} glTF files validated, ${failed} with errors; what remains (files):`);
for (const [code, n] of [...remaining].sort()) console.log(`  ${code}: ${n}`);
fs.rmSync(work, { recursive: true, force: true });
process.exit(failed ? 1 : 0);
