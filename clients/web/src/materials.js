// Replaces every mesh's material with the lightlink surface shader (shading.glsl.js), set
// up for what lights that mesh: the lightmap for static meshes with a lightmap uv (uv1,
// TEXCOORD_1) — `lightlink render`'s rule — and the grid plus direct lights for the rest
// (dynamic meshes, marked `"extras": {"lightlink": {"static": false}}`).
import * as THREE from 'three';
import { vertexShader, fragmentShader } from './shading.glsl.js';

// The scene's punctual lights as the shader's uniform arrays (world space).
function lightUniforms(root) {
  const lights = [];
  root.updateMatrixWorld(true);
  root.traverse((o) => {
    if (!o.isLight || o.isAmbientLight) return;
    const position = new THREE.Vector3().setFromMatrixPosition(o.matrixWorld);
    const direction = new THREE.Vector3();
    if (o.isDirectionalLight || o.isSpotLight)  // GLTFLoader aims them at a child target at (0, 0, -1)
      direction.subVectors(new THREE.Vector3().setFromMatrixPosition(o.target.matrixWorld), position).normalize();
    // three.js's intensities for glTF lights are glTF's: cd (point, spot) and lux (directional).
    const intensity = new THREE.Vector3(o.color.r, o.color.g, o.color.b).multiplyScalar(o.intensity);
    const outer = o.isSpotLight ? o.angle : Math.PI, inner = o.isSpotLight ? o.angle * (1 - o.penumbra) : 0;
    lights.push({ type: o.isSpotLight ? 1 : o.isDirectionalLight ? 2 : 0, position, direction, intensity,
                  range: o.distance ?? 0, cosOuter: Math.cos(outer), cosInner: Math.cos(inner) });
  });
  const pick = (k) => lights.map((l) => l[k]);
  return { count: lights.length, uniforms: {
    lightType: { value: pick('type') }, lightPosition: { value: pick('position') },
    lightDirection: { value: pick('direction') }, lightIntensity: { value: pick('intensity') },
    lightRange: { value: pick('range') }, lightCosOuter: { value: pick('cosOuter') },
    lightCosInner: { value: pick('cosInner') } } };
}

// A node's extras land in its object's userData (the mesh, or the group of a multi-primitive
// mesh's meshes), so the flag is looked up the ancestors too.
function isDynamic(object) {
  for (let o = object; o; o = o.parent) if (o.userData?.lightlink?.static === false) return true;
  return false;
}

export function isLightmapped(mesh) {
  return mesh.geometry.attributes.uv1 !== undefined && !isDynamic(mesh);
}

// A material texture on the uv set it names (GLTFLoader's `channel`: 0 = uv, 1 = uv1), with
// the shader's defines for it; null (with a warning) when the mesh lacks that uv set.
function textureOn(mesh, texture, name, defines) {
  if (!texture) return null;
  const set = texture.channel === 1 ? 1 : 0;
  if (!mesh.geometry.attributes[set === 1 ? 'uv1' : 'uv']) {
    console.warn(`mesh '${mesh.name}': its ${name.toLowerCase()} texture is on uv set ${set}, which it lacks; drawn without it`);
    return null;
  }
  defines[`${name}_MAP`] = 1;
  defines[`${name}_UV`] = `vUv${set}`;
  defines[`USES_UV${set}`] = 1;
  return texture;
}

// The uniforms every material shares for the bake's lighting (loadBakeLighting's result).
function lightingUniforms(lighting) {
  const grid = lighting.grid;
  return {
    shMap: { value: lighting.sh }, validMap: { value: lighting.valid }, lightmapSize: { value: new THREE.Vector2(...lighting.size) },
    directMap: { value: lighting.direct ?? null }, directValidMap: { value: lighting.directValid ?? null },
    directSize: { value: new THREE.Vector2(...(lighting.directSize ?? lighting.size)) },
    gridMap: { value: grid?.texture ?? null }, gridDims: { value: new THREE.Vector3(...(grid?.dims ?? [1, 1, 1])) },
    gridOrigin: { value: new THREE.Vector3(...(grid?.origin ?? [0, 0, 0])) }, gridSpacing: { value: grid?.spacing ?? 1 },
  };
}

function lightingDefines(lighting) {
  return { LIGHTMAP_BANDS: lighting.bands, GRID_BANDS: lighting.grid ? Math.min(lighting.grid.bands, 3) : 0,
           DIRECT_FINER: lighting.directValid ? 1 : undefined };
}

// Returns how many meshes each lighting path got, and `setLighting` / `refreshLights` for
// live mode (new lighting from the daemon, lights moved in the page).
export function applyLightlinkMaterials(root, lighting) {
  const lights = lightUniforms(root);
  const counts = { lightmapped: 0, gridLit: 0, textured: 0 };
  const shared = { ...lightingUniforms(lighting), ...(lights.count > 0 ? lights.uniforms : {}) };
  const materials = [];
  let current = lighting;
  root.traverse((o) => {
    if (!o.isMesh) return;
    const source = o.material;
    const lightmapped = isLightmapped(o);
    const defines = { LIGHT_COUNT: lights.count, LIGHTMAP_BANDS: lighting.bands, GRID_BANDS: lighting.grid ? Math.min(lighting.grid.bands, 3) : 0 };
    if (lightmapped) defines.LIGHTMAPPED = 1;
    if (lighting.directValid) defines.DIRECT_FINER = 1;
    if (lightmapped) defines.USES_UV1 = 1;
    const map = textureOn(o, source.map, 'ALBEDO', defines);
    const emissiveMap = textureOn(o, source.emissiveMap, 'EMISSIVE', defines);
    const albedo = source.color ? new THREE.Vector3(source.color.r, source.color.g, source.color.b) : new THREE.Vector3(1, 1, 1);
    const emission = source.emissive
      ? new THREE.Vector3(source.emissive.r, source.emissive.g, source.emissive.b).multiplyScalar(source.emissiveIntensity ?? 1)
      : new THREE.Vector3();
    o.material = new THREE.RawShaderMaterial({
      glslVersion: THREE.GLSL3, vertexShader, fragmentShader, defines, side: THREE.DoubleSide,
      uniforms: { ...shared, albedo: { value: albedo }, emission: { value: emission }, albedoMap: { value: map }, emissiveMap: { value: emissiveMap } },
    });
    materials.push(o.material);
    ++counts[lightmapped ? 'lightmapped' : 'gridLit'];
    if (map || emissiveMap) ++counts.textured;
  });

  // New lighting (same scene and atlas): textures swapped in place, shaders recompiled only
  // when the encoding or the direct layer's form changed; the old textures are freed.
  const setLighting = (next) => {
    const fresh = lightingUniforms(next);
    for (const [k, u] of Object.entries(fresh)) shared[k].value = u.value;
    const defines = lightingDefines(next);
    for (const m of materials) {
      let changed = false;
      for (const [k, v] of Object.entries(defines)) {
        if (m.defines[k] === v) continue;
        if (v === undefined) delete m.defines[k]; else m.defines[k] = v;
        changed = true;
      }
      if (changed) m.needsUpdate = true;
    }
    for (const t of [current.sh, current.valid, current.direct, current.directValid, current.grid?.texture])
      if (t && !Object.values(shared).some((u) => u.value === t)) t.dispose();
    current = next;
  };
  // Lights moved in the scene graph: the same lights, new positions and directions.
  const refreshLights = () => {
    if (lights.count === 0) return;
    const now = lightUniforms(root).uniforms;
    for (const k of ['lightPosition', 'lightDirection', 'lightIntensity'])
      now[k].value.forEach((v, i) => shared[k].value[i].copy(v));
  };
  return { counts, setLighting, refreshLights };
}
