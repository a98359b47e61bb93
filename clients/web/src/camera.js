// The camera of `lightlink render` (clients/viewer/render.cpp defaultCamera): from the -z side
// of the scene's bounds, looking at their centre, far enough back for the larger of the
// width and height to fit the vertical field of view (times 1.05); up is +y.
import * as THREE from 'three';

export function defaultView(bounds, fovDeg) {
  const c = bounds.getCenter(new THREE.Vector3()), ext = bounds.getSize(new THREE.Vector3());
  const half = 0.5 * Math.max(ext.x, ext.y);
  const dist = (half / Math.tan(0.5 * THREE.MathUtils.degToRad(fovDeg))) * 1.05;
  return { eye: [c.x, c.y, bounds.min.z - dist], target: [c.x, c.y, c.z] };
}

export function makeCamera(params, bounds, aspect) {
  const view = defaultView(bounds, params.fov);
  const eye = params.eye ?? view.eye, target = params.target ?? view.target;
  if (eye.every((v, i) => v === target[i])) throw new Error('camera eye and target must differ');
  const camera = new THREE.PerspectiveCamera(params.fov, aspect, 0.01 * bounds.getSize(new THREE.Vector3()).length() || 0.01, 1e4);
  camera.position.set(...eye);
  camera.up.set(0, 1, 0);
  camera.lookAt(...target);
  return { camera, target: new THREE.Vector3(...target) };
}
