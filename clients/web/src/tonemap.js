// `lightlink render`'s picture rule (clients/viewer/render.cpp): the surface shader writes
// linear radiance to a float target; auto exposure maps the median lit pixel's luminance
// (mean of R, G, B) to 0.5 — a median, so a bright emitter filling part of the frame does not
// darken the rest; then Reinhard x / (1 + x) and the sRGB curve, background black.
import * as THREE from 'three';

// The exposure for radiance `pixels` (RGBA float, A > 0 on geometry): 1 / median luminance.
export function autoExposure(pixels) {
  const lum = [];
  for (let i = 0; i < pixels.length; i += 4) if (pixels[i + 3] > 0) lum.push((pixels[i] + pixels[i + 1] + pixels[i + 2]) / 3);
  if (lum.length === 0) return 1;
  lum.sort((a, b) => a - b);
  const median = lum[lum.length >> 1];  // render's nth_element at size / 2
  return median > 0 ? 1 / median : 1;
}

export function makeTonemapPass() {
  const material = new THREE.RawShaderMaterial({
    glslVersion: THREE.GLSL3,
    uniforms: { radiance: { value: null }, exposure: { value: 1 } },
    vertexShader: /* glsl */ `
      in vec3 position;
      void main() { gl_Position = vec4(position.xy, 0.0, 1.0); }`,
    fragmentShader: /* glsl */ `
      precision highp float;
      uniform highp sampler2D radiance;
      uniform float exposure;
      out vec4 fragColor;
      vec3 srgb(vec3 c) {
        c = clamp(c, 0.0, 1.0);
        return mix(1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, 12.92 * c, lessThanEqual(c, vec3(0.0031308)));
      }
      void main() {
        vec4 r = texelFetch(radiance, ivec2(gl_FragCoord.xy), 0);
        vec3 c = r.rgb * exposure;
        fragColor = vec4(r.a > 0.0 ? srgb(c / (1.0 + c)) : vec3(0.0), 1.0);
      }`,
    depthTest: false,
    depthWrite: false,
  });
  // One triangle over the whole viewport.
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute('position', new THREE.Float32BufferAttribute([-1, -1, 0, 3, -1, 0, -1, 3, 0], 3));
  const mesh = new THREE.Mesh(geometry, material);
  mesh.frustumCulled = false;
  const scene = new THREE.Scene();
  scene.add(mesh);
  const camera = new THREE.OrthographicCamera();
  return {
    draw(renderer, target, exposure) {
      material.uniforms.radiance.value = target.texture;
      material.uniforms.exposure.value = exposure;
      renderer.setRenderTarget(null);
      renderer.render(scene, camera);
    },
  };
}
