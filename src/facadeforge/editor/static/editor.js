// facadeforge edit: the rectified photo with the shape tree over it, the 3D model beside it.
// Every action of the page goes through window.facadeforge (apply, undo, redo, save), the same
// API tests and power users drive.
import { View3D } from './scene3d.js';

const token = new URLSearchParams(location.search).get('token') || '';
const $ = (id) => document.getElementById(id);
const SVG = 'http://www.w3.org/2000/svg';

let tree = null;          // the shape tree, as shape_tree.json
let state = null;         // versions, undo/redo, flags, rules
let selected = [];        // path of the selected shape
let library = [];         // element library entries
let imageSize = [1, 1];   // backdrop pixels
let busy = Promise.resolve();
const view = new View3D($('view3d'));

// -- server ---------------------------------------------------------------------------------
async function call(path, body) {
  const opts = { headers: { 'X-Facadeforge-Token': token } };
  if (body !== undefined) {
    opts.method = 'POST';
    opts.headers['Content-Type'] = 'application/json';
    opts.body = JSON.stringify(body);
  }
  const r = await fetch(path, opts);
  const ct = r.headers.get('content-type') || '';
  const data = ct.includes('json') ? await r.json() : await r.arrayBuffer();
  if (!r.ok) throw new Error((data && data.error) || `${path}: HTTP ${r.status}`);
  return data;
}

function setStatus(text, error = false) {
  $('status').textContent = text;
  $('status').classList.toggle('error', error);
}

async function loadModel() {
  const buf = await call(`/api/model.glb?v=${state.version}`);
  view.setContent([await view.parseGLB(buf)]);
}

async function refresh(data) {
  tree = data.tree;
  state = data.state;
  if (!nodeAt(selected)) selected = [];
  drawOverlay();
  drawInspector();
  await loadModel();
  $('undo').disabled = !state.can_undo;
  $('redo').disabled = !state.can_redo;
  $('save').classList.toggle('primary', state.dirty);
  $('where').textContent = `${state.outdir}${state.facade === '.' ? '' : '/' + state.facade}`;
}

// one request at a time, in order: edits never overtake each other
function queued(fn) {
  const run = busy.then(fn, fn);
  busy = run.catch(() => {});
  return run;
}

async function act(label, path, body) {
  setStatus(`${label}…`);
  try {
    const data = await call(path, body);
    await refresh(data);
    setStatus(`${label}: done (derived in ${state.derive_seconds.toFixed(2)} s)`);
    return data;
  } catch (e) {
    setStatus(`${label}: ${e.message}`, true);
    throw e;
  }
}

// -- tree helpers ------------------------------------------------------------------------------
function nodeAt(path) {
  let n = tree;
  for (const i of path) { if (!n || !n.children[i]) return null; n = n.children[i]; }
  return n;
}
const isInsert = (n) => n.operator === 'insert';
function partition(n) {
  const kids = n.children.map((c, i) => [c, i]).filter(([c]) => !isInsert(c));
  if (!kids.length) return { kids: [], axis: null };
  let axis = kids.map(([c]) => c.params && c.params.axis).find((a) => a === 'x' || a === 'y');
  if (!axis) {
    const w = n.scope.size[0];
    axis = kids.every(([c]) => Math.abs(c.scope.size[0] - w) <= 1e-6 * Math.max(w, 1)) ? 'y' : 'x';
  }
  const k = axis === 'x' ? 0 : 1;
  kids.sort((a, b) => a[0].scope.origin[k] - b[0].scope.origin[k]);
  return { kids, axis };
}
// the shapes an edit of `node` changes, as the server's cluster_of finds them
function clusterMembers(node) {
  const cid = node.tags && node.tags.cluster;
  if (cid === undefined) return [node];
  const { kids, axis } = partition(node);
  const out = [];
  (function walk(n) {
    if (n.symbol === node.symbol && n.tags && n.tags.cluster === cid) {
      const p = partition(n);
      if (!node.children.length || (p.kids.length === kids.length && p.axis === axis)) out.push(n);
    }
    n.children.forEach(walk);
  })(tree);
  return out;
}
// metres (facade frame, y up) → backdrop pixels (y down)
function toPx(node) {
  const box = node.tags && node.tags.box_px;
  if (box) return box;
  const [W, H] = tree.scope.size, [ox, oy] = tree.scope.origin;
  const sx = imageSize[0] / W, sy = imageSize[1] / H;
  const x0 = (node.scope.origin[0] - ox) * sx, x1 = x0 + node.scope.size[0] * sx;
  const y1 = imageSize[1] - (node.scope.origin[1] - oy) * sy, y0 = y1 - node.scope.size[1] * sy;
  return [x0, y0, x1, y1];
}
function pxPerM() {
  const b = toPx(tree);
  return [(b[2] - b[0]) / tree.scope.size[0], (b[3] - b[1]) / tree.scope.size[1]];
}
function hue(text) {
  let h = 0;
  for (const ch of String(text)) h = (h * 31 + ch.charCodeAt(0)) >>> 0;
  return `hsl(${h % 360} 75% 50%)`;
}

// -- the overlay ------------------------------------------------------------------------------
function el(name, attrs, parent) {
  const e = document.createElementNS(SVG, name);
  for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
  if (parent) parent.appendChild(e);
  return e;
}

function drawOverlay() {
  const svg = $('overlay');
  svg.setAttribute('viewBox', `0 0 ${imageSize[0]} ${imageSize[1]}`);
  svg.replaceChildren();
  const sel = nodeAt(selected);
  const members = new Set(sel && selected.length ? clusterMembers(sel) : []);
  const flagged = new Set((state.flags || []).map((f) => JSON.stringify(f.path || null)));
  const leaves = [], lines = [];
  (function walk(n, path, inserted) {
    inserted = inserted || isInsert(n);
    const parts = n.children.filter((c) => !isInsert(c));
    if (!parts.length && path.length) leaves.push([n, path, inserted]);
    if (n.symbol === 'Floor') lines.push([n, 'floor']);
    if (n.symbol === 'Tile') lines.push([n, 'tile']);
    n.children.forEach((c, i) => walk(c, path.concat([i]), inserted));
  })(tree, [], false);
  leaves.sort((a, b) => a[2] - b[2]);      // inserted shapes drawn over the partition
  for (const [n, path, inserted] of leaves) {
    const [x0, y0, x1, y1] = toPx(n);
    const cls = ['shape'];
    if (n.label && n.label !== 'wall') cls.push(inserted ? 'inserted' : 'element');
    if (members.has(n)) cls.push(n === sel ? 'selected' : 'member');
    if (flagged.has(JSON.stringify(path))) cls.push('flagged');
    const r = el('rect', { x: x0, y: y0, width: Math.max(0, x1 - x0), height: Math.max(0, y1 - y0),
      class: cls.join(' '), fill: n.label === 'wall' ? 'transparent' : hue(n.tags.cluster || n.label),
      'data-path': JSON.stringify(path) }, svg);
    const conf = n.tags.confidence !== undefined ? ` · confidence ${n.tags.confidence}` : '';
    el('title', {}, r).textContent = `${n.symbol} ${n.label || ''} ${n.tags.cluster || ''}${conf}`;
    r.addEventListener('click', (ev) => { ev.stopPropagation(); select(path); });
  }
  for (const [n, cls] of lines) {
    const [x0, y0, x1, y1] = toPx(n);
    el('rect', { x: x0, y: y0, width: x1 - x0, height: y1 - y0, class: cls }, svg);
  }
  if (sel && !members.has(sel) && selected.length) {
    const [x0, y0, x1, y1] = toPx(sel);
    el('rect', { x: x0, y: y0, width: x1 - x0, height: y1 - y0, class: 'shape selected', fill: 'none' }, svg);
  }
  drawHandles(svg, sel || tree, sel ? selected : []);
}

// draggable split lines of the selected shape (the facade's floor lines by default)
function drawHandles(svg, node, path) {
  const { kids, axis } = partition(node);
  if (kids.length < 2) return;
  const [ppx, ppy] = pxPerM();
  const [X0, Y0, X1, Y1] = toPx(node);
  for (let k = 1; k < kids.length; k++) {
    const b = toPx(kids[k][0]);
    const at = axis === 'x' ? b[0] : b[3];     // the boundary: left edge / bottom edge of part k
    const coords = axis === 'x' ? { x1: at, x2: at, y1: Y0, y2: Y1 } : { x1: X0, x2: X1, y1: at, y2: at };
    const handle = el('line', { ...coords, class: `handle ${axis}`, 'data-index': k }, svg);
    const line = el('line', { ...coords, class: 'split' }, svg);
    handle.addEventListener('pointerdown', (ev) => {
      ev.preventDefault();
      handle.setPointerCapture(ev.pointerId);
      const m = svg.getScreenCTM().inverse();
      const pt = (e) => new DOMPoint(e.clientX, e.clientY).matrixTransform(m);
      const start = pt(ev);
      line.classList.add('dragging');
      const move = (e) => {
        const p = pt(e);
        const d = axis === 'x' ? p.x - start.x : p.y - start.y;
        for (const l of [handle, line]) {
          if (axis === 'x') { l.setAttribute('x1', at + d); l.setAttribute('x2', at + d); }
          else { l.setAttribute('y1', at + d); l.setAttribute('y2', at + d); }
        }
      };
      const cancel = () => {
        handle.removeEventListener('pointermove', move);
        handle.removeEventListener('pointerup', up);
        handle.removeEventListener('pointercancel', cancel);
        drawOverlay();
      };
      const up = (e) => {
        handle.removeEventListener('pointermove', move);
        handle.removeEventListener('pointerup', up);
        handle.removeEventListener('pointercancel', cancel);
        const p = pt(e);
        const dpx = axis === 'x' ? p.x - start.x : p.y - start.y;
        const delta = axis === 'x' ? dpx / ppx : -dpx / ppy;   // metres, y up
        if (Math.abs(dpx) < 1) { drawOverlay(); return; }
        api.apply({ op: 'move_split', path, index: k, delta: Math.round(delta * 1000) / 1000 })
          .catch(() => drawOverlay());
      };
      handle.addEventListener('pointermove', move);
      handle.addEventListener('pointerup', up);
      handle.addEventListener('pointercancel', cancel);
    });
  }
}

// -- the inspector ----------------------------------------------------------------------------
function select(path) {
  selected = path;
  drawOverlay();
  drawInspector();
}

function row(table, key, value) {
  const tr = table.insertRow();
  tr.insertCell().textContent = key;
  tr.insertCell().textContent = value;
}

function button(parent, text, onclick, title = '') {
  const b = document.createElement('button');
  b.textContent = text;
  b.title = title;
  b.addEventListener('click', onclick);
  parent.appendChild(b);
  return b;
}

function drawInspector() {
  const node = nodeAt(selected) || tree;
  const crumbs = $('crumbs');
  crumbs.replaceChildren();
  for (let d = 0; d <= selected.length; d++) {
    const p = selected.slice(0, d), n = nodeAt(p);
    button(crumbs, n.symbol + (n.tags.cluster ? ` ${n.tags.cluster}` : ''), () => select(p));
  }
  const t = document.createElement('table');
  const members = clusterMembers(node).length;
  row(t, 'path', JSON.stringify(selected));
  row(t, 'symbol', node.symbol);
  if (node.label) row(t, 'label', node.label);
  if (node.tags.cluster) row(t, 'cluster', `${node.tags.cluster} (${members} shape${members > 1 ? 's' : ''})`);
  row(t, 'size', `${node.scope.size[0].toFixed(2)} × ${node.scope.size[1].toFixed(2)} m`);
  if (node.tags.confidence !== undefined) row(t, 'confidence', node.tags.confidence);
  if (node.tags.depth !== undefined) row(t, 'depth', `${node.tags.depth} m`);
  if (node.tags.element) row(t, 'element', node.tags.element);
  const { kids, axis } = partition(node);
  if (kids.length) row(t, 'split', `${axis}: ${kids.length} parts${kids[0][0].tags.split ? ' (' + kids[0][0].tags.split + ')' : ''}`);
  $('details').replaceChildren(t);

  const c = $('controls');
  c.replaceChildren();
  const leaf = !kids.length && selected.length;
  if (leaf) {
    const lab = document.createElement('label');
    lab.textContent = 'Depth of the cluster (m, < 0 recessed)';
    const inp = document.createElement('input');
    inp.type = 'number'; inp.step = '0.05'; inp.id = 'depth-input';
    inp.value = node.tags.depth !== undefined ? node.tags.depth : 0;
    inp.addEventListener('change', () => api.apply({ op: 'set_depth', path: selected, depth: Number(inp.value) }).catch(() => {}));
    c.append(lab, inp);
    const kl = document.createElement('label');
    kl.textContent = 'Kind';
    const sel = document.createElement('select');
    for (const k of ['wall', 'window', 'door', 'balcony', 'shop', 'sill', 'cornice', 'blind', 'deco', 'molding', 'pillar', 'roof']) {
      const o = document.createElement('option');
      o.value = o.textContent = k;
      if (k === node.label) o.selected = true;
      sel.appendChild(o);
    }
    sel.addEventListener('change', () => api.apply({ op: 'set_label', path: selected, label: sel.value }).catch(() => {}));
    c.append(kl, sel);
    const el2 = document.createElement('label');
    el2.textContent = 'Library element';
    const thumbs = document.createElement('div');
    thumbs.className = 'thumbs';
    const choices = library.filter((e) => e.kind === node.label);
    for (const e of choices) {
      const f = document.createElement('figure');
      if (e.name === node.tags.element) f.className = 'current';
      const img = document.createElement('img');
      img.alt = e.name;
      img.src = `/api/thumb/${encodeURIComponent(e.name)}.png`;
      const cap = document.createElement('figcaption');
      cap.textContent = e.name.replace(`${e.kind}_`, '');
      f.append(img, cap);
      f.title = e.name;
      f.addEventListener('click', () => api.apply({ op: 'set_element', path: selected, element: e.name }).catch(() => {}));
      thumbs.appendChild(f);
    }
    if (choices.length) c.append(el2, thumbs);
    if (node.tags.element) {
      const r = document.createElement('div'); r.className = 'row';
      button(r, 'Plain box', () => api.apply({ op: 'set_element', path: selected, element: null }).catch(() => {}),
        'no library element: a recessed or protruding box');
      c.appendChild(r);
    }
  }
  if (kids.length >= 2) {
    const r = document.createElement('div'); r.className = 'row';
    button(r, 'Reverse split', () => api.apply({ op: 'reverse_split', path: selected }).catch(() => {}),
      'the parts in the opposite order');
    c.appendChild(r);
    const types = axis === 'x' ? (kids.length === 3 ? ['dual-x'] : ['left', 'right'])
      : (kids.length === 3 ? ['dual-y'] : ['top', 'bottom']);
    if (kids.length <= 3) {
      const l = document.createElement('label'); l.textContent = 'Split type (how the parts adapt)';
      const s = document.createElement('select');
      s.appendChild(new Option('—', ''));
      for (const ty of types) s.appendChild(new Option(ty, ty, false, kids[0][0].tags.split === ty));
      s.addEventListener('change', () => s.value && api.apply({ op: 'set_split', path: selected, split: s.value }).catch(() => {}));
      c.append(l, s);
    }
  }
  if (selected.length && !isInsert(node)) {
    const r = document.createElement('div'); r.className = 'row';
    const what = node.symbol === 'Floor' ? 'floor' : node.symbol === 'Tile' ? 'column' : 'part';
    button(r, `Add ${what}`, () => api.apply({ op: 'add', path: selected }).catch(() => {}),
      `a copy of this ${what} beside it; the others make room`);
    button(r, `Remove ${what}`, () => api.apply({ op: 'remove', path: selected }).then(
      () => select(selected.slice(0, -1))).catch(() => {}));
    c.appendChild(r);
  }
  if (state.backdrop === 'rectified.png' && (node.children.length || selected.length)) {
    const r = document.createElement('div'); r.className = 'row';
    button(r, 'Re-analyse this region', () => api.apply({ op: 'reanalyse', path: selected }).catch(() => {}),
      'run the photo analysis again inside this shape only; everything outside stays as it is');
    c.appendChild(r);
  }
  const flags = state.flags || [];
  $('flags').textContent = flags.length ? 'Review: ' + flags.map((f) => (typeof f === 'string' ? f : f.message || JSON.stringify(f))).join('; ') : '';
}

// the photo as large as its pane allows (small orthophotos scaled up, tall facades down)
function fitImage() {
  const pane = $('photo-scroll'), img = $('backdrop');
  const w = pane.clientWidth - 16, h = pane.clientHeight - 16;
  if (w <= 0 || h <= 0) return;
  const k = Math.min(w / imageSize[0], h / imageSize[1]);
  img.style.width = `${Math.floor(imageSize[0] * k)}px`;
  img.style.height = `${Math.floor(imageSize[1] * k)}px`;
}

// -- the page API -----------------------------------------------------------------------------
const api = {
  ready: null,
  /** The shape tree as in shape_tree.json (a copy). */
  tree: () => JSON.parse(JSON.stringify(tree)),
  /** Versions, undo/redo state, the current rules text. */
  state: () => JSON.parse(JSON.stringify(state)),
  /** Apply one edit; resolves with what it did once the model is re-derived and redrawn. */
  apply: (edit) => queued(() => act(`${edit && edit.op}`, '/api/apply', edit).then((d) => d.result)),
  undo: () => queued(() => act('undo', '/api/undo', {}).then((d) => d.result)),
  redo: () => queued(() => act('redo', '/api/redo', {}).then((d) => d.result)),
  /** Write shape_tree.json, rules.cga, model.glb/.obj/.city.json… atomically. */
  save: () => queued(() => act('save', '/api/save', {}).then((d) => d.files)),
  select: (path) => select(path),
  /** Share of the 3D canvas that is not background (a check that it drew). */
  drawnFraction: () => view.drawnFraction(),
};
window.facadeforge = api;

api.ready = (async () => {
  const img = $('backdrop');
  const first = await call('/api/state');
  if (first.state.backdrop) {
    img.src = `/api/backdrop.png?token=${encodeURIComponent(token)}`;
    await img.decode();
    imageSize = [img.naturalWidth, img.naturalHeight];
  } else {
    const b = first.tree.tags.box_px || [0, 0, 800, 800 * first.tree.scope.size[1] / first.tree.scope.size[0]];
    imageSize = [b[2], b[3]];
    img.width = imageSize[0]; img.height = imageSize[1];
  }
  fitImage();
  new ResizeObserver(fitImage).observe($('photo-scroll'));
  library = await call('/api/library');
  await refresh(first);
  setStatus(`ready: ${state.edits} unsaved edit(s)`);
  $('undo').addEventListener('click', () => api.undo().catch(() => {}));
  $('redo').addEventListener('click', () => api.redo().catch(() => {}));
  $('save').addEventListener('click', () => api.save().catch(() => {}));
  $('overlay').addEventListener('click', () => select([]));
  document.addEventListener('keydown', (e) => {
    if (!(e.ctrlKey || e.metaKey)) return;
    const k = e.key.toLowerCase();
    if (k === 'z' && !e.shiftKey) { e.preventDefault(); api.undo().catch(() => {}); }
    else if (k === 'y' || (k === 'z' && e.shiftKey)) { e.preventDefault(); api.redo().catch(() => {}); }
    else if (k === 's') { e.preventDefault(); api.save().catch(() => {}); }
  });
  return true;
})();
api.ready.catch((e) => setStatus(`could not load: ${e.message}`, true));
