// facadeforge view: models (glTF, OBJ, CityJSON, 3D Tiles) and point clouds in one scene.
import { View3D, THREE } from './scene3d.js';
import { OBJLoader, MTLLoader } from './vendor/three.bundle.js';

const token = new URLSearchParams(location.search).get('token') || '';
const $ = (id) => document.getElementById(id);
const view = new View3D($('view3d'));
let scene = null;
const objects = [];

async function get(path, kind = 'json') {
  const r = await fetch(path, { headers: { 'X-Facadeforge-Token': token } });
  if (!r.ok) throw new Error(`${path}: HTTP ${r.status}`);
  return kind === 'json' ? r.json() : r.arrayBuffer();
}

function points(buffer) {
  const n = new DataView(buffer).getUint32(0, true);
  const pos = new Float32Array(buffer, 4, n * 3);
  const rgb = new Uint8Array(buffer, 4 + n * 12, n * 3);
  const g = new THREE.BufferGeometry();
  g.setAttribute('position', new THREE.BufferAttribute(pos, 3));
  g.setAttribute('color', new THREE.BufferAttribute(rgb, 3, true));
  const m = new THREE.PointsMaterial({ size: 1.25, sizeAttenuation: false, vertexColors: true });
  return new THREE.Points(g, m);
}

async function load(layer) {
  const url = `/api/layer/${layer.index}`;
  let obj;
  if (layer.kind === 'points') obj = points(await get(url, 'bin'));
  else if (layer.kind === 'gltf') obj = await view.parseGLB(await get(url, 'bin'));
  else if (layer.kind === 'obj') {
    const base = `/api/file/${layer.index}/`;
    const text = new TextDecoder().decode(await get(url, 'bin'));
    const mtl = (text.match(/^mtllib\s+(.+)$/m) || [])[1];
    const loader = new OBJLoader();
    if (mtl) {
      const mats = new MTLLoader().setPath(base).setRequestHeader({ 'X-Facadeforge-Token': token });
      const materials = await mats.loadAsync(mtl.trim());
      materials.preload();
      loader.setMaterials(materials);
    }
    obj = loader.parse(text);
  } else if (layer.kind === 'tiles') {
    obj = new THREE.Group();
    for (const c of layer.info.contents) {
      const g = await view.parseGLB(await get(`/api/file/${layer.index}/${c.uri}`, 'bin'));
      g.matrixAutoUpdate = false;
      g.matrix.fromArray(c.matrix);
      obj.add(g);
    }
  }
  obj.position.set(...layer.offset);
  obj.name = layer.name;
  return obj;
}

function legend() {
  const box = $('layers');
  box.replaceChildren();
  scene.layers.forEach((layer, i) => {
    const lab = document.createElement('label');
    const cb = document.createElement('input');
    cb.type = 'checkbox'; cb.checked = true;
    cb.addEventListener('change', () => { objects[i].visible = cb.checked; view.render(); });
    lab.append(cb, ` ${layer.name}`);
    const info = document.createElement('small');
    const parts = Object.entries(layer.info).filter(([k]) => k !== 'contents').map(([k, v]) => `${k}: ${v}`);
    info.textContent = `${layer.kind}${parts.length ? ' · ' + parts.join(' · ') : ''}`;
    box.append(lab, info);
  });
}

const api = {
  ready: null,
  scene: () => JSON.parse(JSON.stringify(scene)),
  drawnFraction: () => view.drawnFraction(),
};
window.facadeforge = api;

api.ready = (async () => {
  scene = await get('/api/scene');
  for (const layer of scene.layers) objects.push(await load(layer));
  view.setContent(objects, true);
  legend();
  $('status').textContent = `${scene.layers.length} layer(s)`;
  return true;
})();
api.ready.catch((e) => { $('status').textContent = `could not load: ${e.message}`; $('status').classList.add('error'); });
