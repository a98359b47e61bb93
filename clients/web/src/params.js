// The page's URL parameters: which bake to draw and from where. The camera parameters are
// those of `lightlink render` (--eye, --target, --fov, --width, --height, --exposure), so a
// URL and a command line give the same picture; a bad value is an error that names it.

function numbers(params, name, count) {
  const text = params.get(name);
  if (text === null) return null;
  const values = text.split(',').map((s) => Number(s.trim()));
  if (values.length !== count || values.some((v) => !Number.isFinite(v)))
    throw new Error(`URL parameter ${name}=${text}: expected ${count} comma-separated finite numbers`);
  return values;
}

function positiveInt(params, name, max) {
  const text = params.get(name);
  if (text === null) return null;
  const v = Number(text);
  if (!Number.isInteger(v) || v < 1 || v > max) throw new Error(`URL parameter ${name}=${text}: expected an integer in 1..${max}`);
  return v;
}

export function readParams(search) {
  const params = new URLSearchParams(search);
  const bake = params.get('bake');
  if (!bake) throw new Error('no bake folder: open the page as index.html?bake=path/to/bake/ (docs/web.md)');
  const fovText = params.get('fov');
  const fov = fovText === null ? 40 : Number(fovText);  // render's default vertical field of view
  if (!(fov > 0 && fov < 179)) throw new Error(`URL parameter fov=${fovText}: expected degrees in (0, 179)`);
  const exposureText = params.get('exposure');
  const exposure = exposureText === null ? 0 : Number(exposureText);
  if (!(exposure >= 0) || !Number.isFinite(exposure)) throw new Error(`URL parameter exposure=${exposureText}: expected a number >= 0 (0: auto)`);
  const width = positiveInt(params, 'width', 16384), height = positiveInt(params, 'height', 16384);
  if ((width === null) !== (height === null)) throw new Error('URL parameters width and height go together');
  return {
    // A folder: resolved with a trailing slash so the files resolve inside it.
    bakeUrl: new URL(bake.endsWith('/') ? bake : `${bake}/`, globalThis.location?.href ?? 'file:///').href,
    gltf: params.get('gltf'),  // the glTF's name in the bake folder; default: from report.json
    eye: numbers(params, 'eye', 3),
    target: numbers(params, 'target', 3),
    fov,
    exposure,
    size: width === null ? null : { width, height },
    ui: params.get('ui') !== '0',  // ui=0: no status line over the picture (screenshots)
    live: params.get('live') === '1',  // live=1: relight through the gateway that serves the page
  };
}
