// Reads a bake's lighting as the glTF's LIGHTLINK_lighting extension describes it
// (docs/outputs.md): the SH lightmap (lightmap_<c>.exr in SH index order, valid.exr,
// direct.exr and, with a finer direct layer, direct_valid.exr) or, for an L0 bake, only
// irradiance.exr; and the grid from grid.raw (float32, what `lightlink render` reads too).
// Everything becomes float textures the shader reads texel by texel (texelFetch), because
// it weights the four bilinear taps by validity as `lightlink render` does, which hardware
// filtering cannot.
import * as THREE from 'three';
import { EXRLoader } from 'three/addons/loaders/EXRLoader.js';
import { fetchFile } from './fetch_file.js';

// One EXR as { width, height, channels, data }, rows in file order (row 0 = glTF v = 0):
// EXRLoader returns them bottom-up (OpenGL's order), so they are flipped back here and the
// shader indexes texel (x, y) at uv1 * size with no flip.
async function readExr(url) {
  const parsed = new EXRLoader().setDataType(THREE.FloatType).parse(await fetchFile(url));
  const { width, height } = parsed;
  const channels = parsed.data.length / (width * height);
  if (!Number.isInteger(channels)) throw new Error(`${url}: ${parsed.data.length} values for ${width}x${height} texels`);
  const data = new Float32Array(parsed.data.length), row = width * channels;
  for (let y = 0; y < height; ++y) data.set(parsed.data.subarray((height - 1 - y) * row, (height - y) * row), y * row);
  return { url, width, height, channels, data };
}

function expectSize(img, width, height) {
  if (img.width !== width || img.height !== height)
    throw new Error(`${img.url}: ${img.width}x${img.height} texels, but the lightmap has ${width}x${height}`);
}

// RGB files stacked as the layers of one RGBA float array texture (alpha unused).
function rgbLayers(images) {
  const { width, height } = images[0], texels = width * height;
  const data = new Float32Array(4 * texels * images.length);
  images.forEach((img, layer) => {
    expectSize(img, width, height);
    if (img.channels < 3) throw new Error(`${img.url}: ${img.channels} channels, expected R, G, B`);
    for (let t = 0; t < texels; ++t)
      for (let c = 0; c < 3; ++c) data[4 * (layer * texels + t) + c] = img.data[img.channels * t + c];
  });
  return floatTexture(new THREE.DataArrayTexture(data, width, height, images.length));
}

// A Y (validity) file as a one-channel float texture, 1 where the texel holds a value.
function validTexture(img, width, height) {
  expectSize(img, width, height);
  const data = new Float32Array(width * height);
  for (let t = 0; t < data.length; ++t) data[t] = img.data[img.channels * t] > 0.5 ? 1 : 0;
  const tex = floatTexture(new THREE.DataTexture(data, width, height, THREE.RedFormat));
  return tex;
}

function floatTexture(tex) {
  tex.type = THREE.FloatType;
  tex.minFilter = tex.magFilter = THREE.NearestFilter;  // read with texelFetch only
  tex.generateMipmaps = false;
  tex.needsUpdate = true;
  return tex;
}

// grid.raw (docs/outputs.md "Grid"): "LLGRID01", u64 version, u32 bands, u32 dims[3],
// f32 origin[3], f32 spacing, then per point 3 * bands^2 float32 (R coefficients, then G,
// then B), then one validity byte per point; point (x, y, z) at (z * dims.y + y) * dims.x + x.
export function parseGridRaw(buffer, url) {
  const view = new DataView(buffer);
  if (buffer.byteLength < 48 || new TextDecoder().decode(new Uint8Array(buffer, 0, 8)) !== 'LLGRID01')
    throw new Error(`${url} is not a lightlink grid (bad magic or shorter than its 48-byte header)`);
  const bands = view.getUint32(16, true);
  const dims = [0, 1, 2].map((a) => view.getUint32(20 + 4 * a, true));
  const origin = [0, 1, 2].map((a) => view.getFloat32(32 + 4 * a, true));
  const spacing = view.getFloat32(44, true);
  if (bands < 1 || bands > 4) throw new Error(`${url}: bands ${bands} (must be 1..4)`);
  const points = dims[0] * dims[1] * dims[2];
  if (!(points >= 1 && points <= 1 << 24)) throw new Error(`${url}: dims ${dims.join(' x ')} out of range`);
  if (!(spacing > 0) || !origin.every(Number.isFinite)) throw new Error(`${url}: origin or spacing is not finite and positive`);
  const per = 3 * bands * bands;
  if (buffer.byteLength !== 48 + points * (4 * per + 1))
    throw new Error(`${url}: ${buffer.byteLength} bytes, but bands ${bands} and dims ${dims.join(' x ')} need ${48 + points * (4 * per + 1)}`);
  const sh = new Float32Array(buffer.slice(48, 48 + 4 * per * points));
  const valid = new Uint8Array(buffer, 48 + 4 * per * points, points);
  return { bands, dims, origin, spacing, sh, valid };
}

// The grid as a 3D RGBA float texture: coefficient k of point (x, y, z) at texel
// (x, y, z + k * dims.z), RGB = its three channels, A = the point's validity.
function gridTexture(grid) {
  const [dx, dy, dz] = grid.dims, nc = grid.bands * grid.bands, points = dx * dy * dz;
  const data = new Float32Array(4 * points * nc);
  for (let p = 0; p < points; ++p)
    for (let k = 0; k < nc; ++k) {
      const o = 4 * (k * points + p);  // layer k of dz slices, then the point's own index
      for (let c = 0; c < 3; ++c) data[o + c] = grid.sh[p * 3 * nc + c * nc + k];
      data[o + 3] = grid.valid[p];
    }
  return floatTexture(new THREE.Data3DTexture(data, dx, dy, dz * nc));
}

// Everything the shader needs, from the glTF's LIGHTLINK_lighting description.
export async function loadBakeLighting(description, baseUrl) {
  if (!description) throw new Error('the glTF has no LIGHTLINK_lighting extension: open the *_lm.gltf that `lightlink bake` wrote');
  if (description.version !== 2 || description.exr_layout !== 2)
    throw new Error(`LIGHTLINK_lighting version ${description.version}, EXR layout ${description.exr_layout}: this viewer reads version 2, layout 2 (bake again)`);
  const url = (name) => new URL(name, baseUrl).href;
  const lm = description.lightmap ?? {};
  const out = { bands: 0, grid: null };
  if (lm.sh?.length) {  // L1 or L2: the SH set, direct and validity
    const files = lm.sh.slice(0, 9);  // band 3 (glossy sets) has A_3 = 0 in irradiance
    const images = await Promise.all(files.map((f) => readExr(url(f))));
    const { width, height } = images[0];
    out.bands = Math.round(Math.sqrt(files.length));
    if (out.bands * out.bands !== files.length) throw new Error(`LIGHTLINK_lighting lists ${files.length} SH files, not a square number`);
    out.sh = rgbLayers(images);
    out.size = [width, height];
    out.valid = validTexture(await readExr(url(lm.valid ?? 'valid.exr')), width, height);
    const direct = await readExr(url(lm.direct?.uri ?? 'direct.exr'));
    out.direct = rgbLayers([direct]);
    out.directSize = [direct.width, direct.height];
    out.directValid = lm.direct?.valid
      ? validTexture(await readExr(url(lm.direct.valid)), direct.width, direct.height)
      : null;  // the direct layer has the lightmap's texels and validity
    if (!out.directValid) expectSize(direct, width, height);
  } else if (description.irradiance?.uri) {  // L0: irradiance for the surface's normal, direct included
    const irradiance = await readExr(url(description.irradiance.uri));
    out.sh = rgbLayers([irradiance]);
    out.size = [irradiance.width, irradiance.height];
    out.valid = null;  // every texel counts, as an engine samples the map
  } else {
    throw new Error('LIGHTLINK_lighting names neither lightmap SH files nor irradiance.exr');
  }
  const raw = description.grid?.raw?.uri;
  if (raw) {
    const grid = parseGridRaw(await fetchFile(url(raw)), url(raw));
    out.grid = { ...grid, texture: gridTexture(grid) };
  }
  return out;
}
