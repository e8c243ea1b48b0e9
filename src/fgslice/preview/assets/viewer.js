// fgslice viewer: draws a G-code file's segments, served by fgslice.preview.viewer.
// Data: data/meta.json plus binary arrays (see viewer.py). Segments are sorted by layer,
// so a layer range is one draw range of one LineSegments per kind (extrusions, travels).
// Colors are sRGB bytes passed through unchanged (color management off). Frames are
// drawn on demand, at most one per animation frame.
import * as THREE from './three.module.min.js';
import { OrbitControls } from './OrbitControls.js';

const BACKGROUND = 0x1e2127;
const TRAVEL_COLOR = 0x4a90e2;
// Multisampling quadruples the fragments of software renderers; past this many
// segments lines are dense enough to draw without it.
const ANTIALIAS_LIMIT = 1_000_000;
const $ = (id) => document.getElementById(id);

async function fetchBuffer(name) {
  const response = await fetch(`data/${name}`);
  if (!response.ok) throw new Error(`${name}: HTTP ${response.status}`);
  return response.arrayBuffer();
}

async function load() {
  const [meta, extrusions, travels, states, roles] = await Promise.all([
    fetch('data/meta.json').then((r) => r.json()),
    fetchBuffer('extrusions.bin'), fetchBuffer('travels.bin'),
    fetchBuffer('states.bin'), fetchBuffer('roles.bin'),
  ]);
  const stateArray = meta.state_bytes === 4 ? new Uint32Array(states) : new Uint16Array(states);
  return { meta, extrusions: new Float32Array(extrusions), travels: new Float32Array(travels),
           states: stateArray, roles: new Uint8Array(roles) };
}

function segmentGeometry(positions, colors, bbox) {
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute('position', new THREE.BufferAttribute(positions, 3));
  if (colors) geometry.setAttribute('color', new THREE.BufferAttribute(colors, 3, true));
  const box = new THREE.Box3(new THREE.Vector3(...bbox[0]), new THREE.Vector3(...bbox[1]));
  geometry.boundingBox = box;
  geometry.boundingSphere = box.getBoundingSphere(new THREE.Sphere());
  return geometry;
}

function colorTables(meta) {
  const table = (items) => {
    const out = new Uint8Array(items.length * 3);
    items.forEach((item, i) => out.set(item.color, 3 * i));
    return out;
  };
  const toolIndex = new Map(meta.tools.map((t, i) => [t.tool, i]));
  const stateTools = meta.states.map((s) => ({ color: meta.tools[toolIndex.get(s.tool)].color }));
  return { state: table(meta.states), role: table(meta.roles), tool: table(stateTools) };
}

function recolor(colors, attribute, table) {
  for (let i = 0, n = attribute.length; i < n; i++) {
    const t = 3 * attribute[i], o = 6 * i;
    colors[o] = colors[o + 3] = table[t];
    colors[o + 1] = colors[o + 4] = table[t + 1];
    colors[o + 2] = colors[o + 5] = table[t + 2];
  }
}

function legendItems(mode, data) {
  const { meta } = data;
  const rgb = (c) => `rgb(${c[0]},${c[1]},${c[2]})`;
  if (mode === 'role') {
    const used = new Uint8Array(meta.roles.length);
    for (const r of data.roles) used[r] = 1;
    return meta.roles.filter((_, i) => used[i]).map((r) => [rgb(r.color), r.name]);
  }
  const counts = new Float64Array(meta.states.length);
  for (const s of data.states) counts[s] += 1;
  if (mode === 'tool') {
    const used = new Set(meta.states.filter((_, i) => counts[i]).map((s) => s.tool));
    return meta.tools.filter((t) => used.has(t.tool)).map((t) => [rgb(t.color), `T${t.tool}`]);
  }
  const total = data.states.length || 1;
  return meta.states.map((s, i) => [i, s]).filter(([i]) => counts[i])
    .map(([i, s]) => [rgb(s.color), `${s.label} (${(100 * counts[i] / total).toFixed(1)}%)`]);
}

function showLegend(items) {
  const list = $('legend');
  list.replaceChildren(...items.map(([color, text]) => {
    const li = document.createElement('li');
    const swatch = document.createElement('span');
    swatch.className = 'swatch';
    swatch.style.background = color;
    li.append(swatch, document.createTextNode(text));
    return li;
  }));
}

function showStats(meta) {
  $('stats').replaceChildren(...meta.stats.map(([key, value]) => {
    const row = document.createElement('tr');
    for (const text of [key, value]) {
      const cell = document.createElement('td');
      cell.textContent = text;
      row.append(cell);
    }
    return row;
  }));
}

function bedOutline(meta) {
  if (!meta.bed) return null;
  const [x, y] = meta.bed;
  const points = new Float32Array([0, 0, 0, x, 0, 0, x, 0, 0, x, y, 0, x, y, 0, 0, y, 0, 0, y, 0, 0, 0, 0]);
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute('position', new THREE.BufferAttribute(points, 3));
  return new THREE.LineSegments(geometry, new THREE.LineBasicMaterial({ color: 0x5a606b }));
}

function start(data) {
  const { meta } = data;
  THREE.ColorManagement.enabled = false;
  const view = $('view');
  const renderer = new THREE.WebGLRenderer({ antialias: meta.extrusion_count < ANTIALIAS_LIMIT });
  renderer.outputColorSpace = THREE.LinearSRGBColorSpace;
  renderer.setPixelRatio(window.devicePixelRatio);
  view.append(renderer.domElement);
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(BACKGROUND);

  const colors = new Uint8Array(data.states.length * 6);
  const extrusions = new THREE.LineSegments(segmentGeometry(data.extrusions, colors, meta.bbox),
                                            new THREE.LineBasicMaterial({ vertexColors: true }));
  const travels = new THREE.LineSegments(segmentGeometry(data.travels, null, meta.bbox),
                                         new THREE.LineBasicMaterial({ color: TRAVEL_COLOR, transparent: true, opacity: 0.5 }));
  travels.visible = false;
  scene.add(extrusions, travels);
  const bed = bedOutline(meta);
  if (bed) scene.add(bed);

  const [lo, hi] = meta.bbox.map((p) => new THREE.Vector3(...p));
  const center = lo.clone().add(hi).multiplyScalar(0.5);
  const size = Math.max(hi.clone().sub(lo).length(), 1);
  const camera = new THREE.PerspectiveCamera(40, 1, size / 1000, size * 20);
  camera.up.set(0, 0, 1);
  camera.position.copy(center).add(new THREE.Vector3(0.6 * size, -1.2 * size, 0.9 * size));
  const controls = new OrbitControls(camera, renderer.domElement);
  controls.target.copy(center);
  controls.update();

  let pending = false;
  const render = () => {
    if (pending) return;
    pending = true;
    requestAnimationFrame(() => { pending = false; renderer.render(scene, camera); });
  };
  controls.addEventListener('change', render);
  new ResizeObserver(() => {
    const { clientWidth: w, clientHeight: h } = view;
    renderer.setSize(w, h, false);
    camera.aspect = w / Math.max(h, 1);
    camera.updateProjectionMatrix();
    render();
  }).observe(view);

  const tables = colorTables(meta);
  const attributeOf = { state: data.states, role: data.roles, tool: data.states };
  const setMode = (mode) => {
    recolor(colors, attributeOf[mode], tables[mode]);
    extrusions.geometry.attributes.color.needsUpdate = true;
    showLegend(legendItems(mode, data));
    render();
  };

  const info = $('layer-info');
  const minInput = $('layer-min'), maxInput = $('layer-max');
  const last = meta.layer_count - 1;
  for (const input of [minInput, maxInput]) input.max = String(last);
  maxInput.value = String(last);
  const setRange = (changed) => {
    let a = Number(minInput.value), b = Number(maxInput.value);
    if (a > b) {
      if (changed === minInput) b = a; else a = b;
      minInput.value = String(a);
      maxInput.value = String(b);
    }
    const e = meta.extrusion_offsets, t = meta.travel_offsets;
    extrusions.geometry.setDrawRange(2 * e[a], 2 * (e[b + 1] - e[a]));
    travels.geometry.setDrawRange(2 * t[a], 2 * (t[b + 1] - t[a]));
    const z = meta.layer_z[b];
    info.textContent = `layers ${a}-${b} of ${meta.layer_count}` + (z === undefined ? '' : ` (z ${z} mm)`);
    Object.assign(info.dataset, { layerCount: meta.layer_count, layerMin: a, layerMax: b,
                                  segmentsDrawn: e[b + 1] - e[a] });
    render();
  };
  minInput.addEventListener('input', () => setRange(minInput));
  maxInput.addEventListener('input', () => setRange(maxInput));
  window.addEventListener('keydown', (event) => {
    if (event.target instanceof HTMLInputElement || event.target instanceof HTMLSelectElement) return;
    const step = { ArrowUp: 1, ArrowDown: -1 }[event.key];
    if (!step) return;
    maxInput.value = String(Math.min(last, Math.max(0, Number(maxInput.value) + step)));
    setRange(maxInput);
    event.preventDefault();
  });
  $('color-mode').addEventListener('change', (event) => setMode(event.target.value));
  $('show-travels').addEventListener('change', (event) => { travels.visible = event.target.checked; render(); });

  $('file-name').textContent = meta.name;
  document.title = `${meta.name} - fgslice viewer`;
  showStats(meta);
  setMode($('color-mode').value);
  setRange(maxInput);
  info.dataset.loadMs = String(Math.round(performance.now()));
  info.dataset.ready = '1';
}

load().then(start).catch((error) => {
  const info = $('layer-info');
  info.textContent = `cannot show the file: ${error.message}`;
  info.dataset.error = error.message;
  console.error(error);
});
