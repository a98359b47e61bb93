// Live mode (docs/web.md "Live mode"): the page, served by `lightlink serve --http`, asks the
// gateway to make its bake live on the daemon, then
// - receives each new version over Server-Sent Events and swaps its lighting in (the files a
//   bake writes, from the gateway's version folder);
// - sends light moves (drag handles, or `lightlinkViewer.live.moveLight`) as light-set
//   documents, coalesced: one request in flight, the newest position next;
// - blends the bake's scenarios with sliders (UseScenarios on the daemon).
// Latency of a light change: from sending it to the first frame drawn with a version that
// includes it (that version or a newer one), in `lightlinkViewer.live.latencies` (ms).
import * as THREE from 'three';
import { TransformControls } from 'three/addons/controls/TransformControls.js';
import { loadBakeLighting } from './bake_lighting.js';

async function postJson(url, body) {
  const res = await fetch(url, { method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(body) });
  const json = await res.json().catch(() => ({}));
  if (!res.ok) throw new Error(`${url}: ${json.error ?? res.statusText}`);
  return json;
}

// Sends the newest of a stream of requests, one at a time: a drag produces far more
// positions than a relight can follow, and only the last one matters.
function coalescer(send) {
  let pending = null, busy = false;
  const pump = async () => {
    if (busy || !pending) return;
    busy = true;
    const job = pending;
    pending = null;
    try { await send(job); } catch (e) { console.error(e); job.onError?.(e); }
    busy = false;
    pump();
  };
  return (job) => { pending = job; pump(); };
}

export async function startLive({ params, gltf, scene, camera, canvas, orbit, materials, draw, say }) {
  const bakePath = new URL(params.bakeUrl).pathname;
  const info = await postJson('/api/live', { bake: bakePath });
  const live = {
    sceneId: info.scene_id, sceneToken: info.scene_token, lightIds: info.light_ids, scenarios: info.scenarios,
    lights: info.lights,
    version: 0, shownAt: 0, latencies: [], frameMs: 0, events: 0, error: null,
    stages: [],  // per version shown: relight_ms, write_ms (gateway), load_ms (fetch + decode), draw_ms
  };
  const sent = [];  // { version, t0 } of light changes not yet on screen

  // The glTF nodes of the lights the bake knows (report.json source.light_nodes).
  const nodes = new Map();
  for (const [id, index] of Object.entries(info.light_nodes ?? {}))
    nodes.set(id, await gltf.parser.getDependency('node', index));

  const worldPosition = (o) => new THREE.Vector3().setFromMatrixPosition(o.matrixWorld);
  const placeNode = (node, p) => {
    const local = node.parent ? node.parent.worldToLocal(p.clone()) : p.clone();
    node.position.copy(local);
    node.updateMatrixWorld(true);
  };

  const sendLight = coalescer(async ({ id, position }) => {
    const t0 = performance.now();
    const r = await postJson(`/api/live/${live.sceneId}/lights`, { version: 1, lights: [{ id, position }] });
    sent.push({ version: r.version, t0 });
  });

  // Moves light `id` to world position [x, y, z]: in the page at once (its handle, the direct
  // light of grid-lit objects), on the daemon through the gateway.
  // A light the bake added (a light-set file, no glTF node) moves on the daemon only: the page
  // draws its light through the lightmap and grid, not as a direct light of grid-lit objects.
  const known = new Set([...(info.light_ids ?? []), ...(info.lights?.lights ?? []).map((l) => l.id)]);
  live.moveLight = (id, position) => {
    const node = nodes.get(id);
    if (!node && !known.has(id)) throw new Error(`no light ${id} in this scene (lights: ${[...known].join(', ')})`);
    if (node) {
      placeNode(node, new THREE.Vector3(...position));
      live.onLightMoved?.(id, position);
      materials.refreshLights();
      draw(false);
    }
    sendLight({ id, position: [...position] });
  };

  const sendBlend = coalescer(async (weights) => {
    const t0 = performance.now();
    const r = await postJson(`/api/live/${live.sceneId}/scenarios`, { weights });
    sent.push({ version: r.version, t0 });
  });
  live.blendScenarios = (weights) => sendBlend(weights);

  // Versions: load the newest, one at a time.
  let loading = false, newest = null;
  const show = async () => {
    if (loading || !newest || newest.version <= live.version) return;
    loading = true;
    const ev = newest;
    try {
      const tLoad = performance.now();
      const lighting = await loadBakeLighting(ev.lighting, new URL(ev.url, location.href).href);
      const loadMs = performance.now() - tLoad;
      materials.setLighting(lighting);
      // Lights moved through the gateway by another page (or this one): follow them.
      for (const l of ev.lights?.lights ?? []) {
        const node = nodes.get(l.id);
        if (!node || !Array.isArray(l.position)) continue;
        placeNode(node, new THREE.Vector3(...l.position));
        live.onLightMoved?.(l.id, l.position);
      }
      materials.refreshLights();
      const t = performance.now();
      draw(false);  // the exposure of the settled view: a brighter light looks brighter
      await new Promise((resolve) => requestAnimationFrame(resolve));
      const now = performance.now();
      live.frameMs = now - t;
      live.stages.push({ version: ev.version, relight_ms: ev.relight_ms, write_ms: ev.write_ms, load_ms: loadMs, draw_ms: now - t });
      live.version = ev.version;
      live.shownAt = now;
      live.error = null;
      for (let i = sent.length - 1; i >= 0; --i)
        if (sent[i].version <= ev.version) { live.latencies.push(now - sent[i].t0); sent.splice(i, 1); }
      const last = live.latencies.at(-1);
      say(`live: scene ${live.sceneId} version ${ev.version} (relight ${ev.relight_ms.toFixed(1)} ms)` +
          (last !== undefined ? `; last change to pixels ${last.toFixed(0)} ms` : ''));
    } catch (e) {
      // A version replaced while it loaded is gone from the gateway (it keeps the newest few):
      // the newer one follows. Only a failure of the newest is an error.
      if (!(newest.version > ev.version)) {
        live.error = e.message;
        say(`live: ${e.message}`);
        console.error(e);
      }
    }
    loading = false;
    show();
  };
  // The event stream; when the gateway ends it (the daemon restarted, the scene was closed),
  // the bake is made live again, under a new scene id, and versions count from there.
  const listen = (url) => {
    const events = new EventSource(url);
    events.addEventListener('version', (m) => {
      ++live.events;
      newest = JSON.parse(m.data);
      show();
    });
    events.addEventListener('ended', () => {
      events.close();
      document.body.dataset.live = 'reconnecting';
      say('live: the daemon ended the scene\'s stream; opening the bake again');
      const retry = (delay) => setTimeout(() => postJson('/api/live', { bake: bakePath }).then((again) => {
        Object.assign(live, { sceneId: again.scene_id, sceneToken: again.scene_token, version: 0 });
        newest = null;
        listen(again.events);
      }).catch((e) => { say(`live: ${e.message}; retrying`); retry(Math.min(2 * delay, 10000)); }), delay);
      retry(1000);
    });
    events.onerror = () => { document.body.dataset.live = 'reconnecting'; };
    events.onopen = () => { document.body.dataset.live = 'connected'; };
  };
  listen(info.events);

  if (params.ui) addControls({ live, nodes, scene, camera, canvas, orbit, draw, worldPosition, info });
  return live;
}

// People's controls: a handle per light (click it, drag the arrows) and scenario sliders.
function addControls({ live, nodes, scene, camera, canvas, orbit, draw, worldPosition, info }) {
  const handles = [];
  for (const [id, node] of nodes) {
    const handle = new THREE.Mesh(new THREE.SphereGeometry(1, 12, 8), new THREE.MeshBasicMaterial({ color: 0xffcc44 }));
    handle.userData.lightId = id;
    handle.position.copy(worldPosition(node));
    handles.push(handle);
    scene.add(handle);
  }
  const box = new THREE.Box3().setFromObject(scene);
  const radius = 0.015 * box.getSize(new THREE.Vector3()).length();
  handles.forEach((h) => h.scale.setScalar(radius));

  live.onLightMoved = (id, p) => {
    const h = handles.find((x) => x.userData.lightId === id);
    if (h && gizmo.object !== h) h.position.set(...p);
  };
  const gizmo = new TransformControls(camera, canvas);
  scene.add(gizmo.getHelper());
  gizmo.addEventListener('change', () => draw(false));
  gizmo.addEventListener('dragging-changed', (e) => { orbit.enabled = !e.value; });
  gizmo.addEventListener('objectChange', () => {
    const h = gizmo.object;
    live.moveLight(h.userData.lightId, h.position.toArray());
  });
  const ray = new THREE.Raycaster();
  canvas.addEventListener('pointerdown', (e) => {
    const r = canvas.getBoundingClientRect();
    ray.setFromCamera(new THREE.Vector2(((e.clientX - r.left) / r.width) * 2 - 1, -((e.clientY - r.top) / r.height) * 2 + 1), camera);
    const hit = ray.intersectObjects(handles)[0];
    if (hit) { gizmo.attach(hit.object); draw(false); }
  });

  const names = info.scenarios ?? [];
  if (names.length === 0) return;
  const panel = document.createElement('div');
  panel.id = 'scenarios';
  const weights = Object.fromEntries(names.map((n) => [n, 0]));
  const slider = (label, oninput) => {
    const row = document.createElement('label');
    row.textContent = label;
    const input = Object.assign(document.createElement('input'), { type: 'range', min: 0, max: 1, step: 0.01, value: 0 });
    input.addEventListener('input', () => oninput(Number(input.value)));
    row.append(input);
    panel.append(row);
  };
  if (names.length === 2) {  // a cross-fade: day <-> night
    slider(`${names[0]} \u2194 ${names[1]}`, (t) => live.blendScenarios({ [names[0]]: 1 - t, [names[1]]: t }));
  } else {
    for (const n of names) slider(n, (w) => { weights[n] = w; live.blendScenarios({ ...weights }); });
  }
  document.body.append(panel);
}
