/*! @license three.js (https://threejs.org), bundled below:
The MIT License

Copyright © 2010-2026 three.js authors

Permission is hereby granted, free of charge, to any person obtaining a copy
of this software and associated documentation files (the "Software"), to deal
in the Software without restriction, including without limitation the rights
to use, copy, modify, merge, publish, distribute, sublicense, and/or sell
copies of the Software, and to permit persons to whom the Software is
furnished to do so, subject to the following conditions:

The above copyright notice and this permission notice shall be included in
all copies or substantial portions of the Software.

THE SOFTWARE IS PROVIDED "AS IS", WITHOUT WARRANTY OF ANY KIND, EXPRESS OR
IMPLIED, INCLUDING BUT NOT LIMITED TO THE WARRANTIES OF MERCHANTABILITY,
FITNESS FOR A PARTICULAR PURPOSE AND NONINFRINGEMENT. IN NO EVENT SHALL THE
AUTHORS OR COPYRIGHT HOLDERS BE LIABLE FOR ANY CLAIM, DAMAGES OR OTHER
LIABILITY, WHETHER IN AN ACTION OF CONTRACT, TORT OR OTHERWISE, ARISING FROM,
OUT OF OR IN CONNECTION WITH THE SOFTWARE OR THE USE OR OTHER DEALINGS IN
THE SOFTWARE.
*/

// The interactive 3D view of heatwave's HTML audit report (report/viewer_embed.h writes
// the page fragment this script reads). Every colour was computed by the C++ side with the
// functions that draw the report's static images; this script only draws them, shaded
// like the images (ambient + diffuse · |cos incidence| with a headlight at the eye), with
// the unobserved surface hatched in screen space like the images.
//
// Per container <div class="hw-viewer">:
//   <script type="application/json" class="hw-viewer-meta">  counts, offsets, box, markers
//   <script type="application/octet-stream" class="hw-viewer-data">  base64 binary:
//     positions uint16×3 per vertex (quantised over the box), indices uint16/uint32×3 per
//     face, 4 × sRGB8×3 per vertex (thermal, colour, ih, highlight), unobserved uint8 per
//     vertex. Little endian.
// Sets document.documentElement.dataset.hwViewer to "rendered" after the first frame, or
// "failed" (the canvas is hidden and a message shown; the static images remain).

import * as THREE from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';

const MODES = ['thermal', 'colour', 'ih', 'highlight'];

function countCspViolations() {
  const root = document.documentElement;
  if (root.dataset.hwCspListening) return;
  root.dataset.hwCspListening = '1';
  document.addEventListener('securitypolicyviolation', () => {
    root.dataset.hwCspViolations = String(Number(root.dataset.hwCspViolations || '0') + 1);
  });
}

function decodeBase64(text) {
  const binary = atob(text.replace(/\s+/g, ''));
  const bytes = new Uint8Array(binary.length);
  for (let i = 0; i < binary.length; ++i) bytes[i] = binary.charCodeAt(i);
  return bytes.buffer;
}

// The mesh data: base64 of a zlib stream (meta.compression "deflate") or of the raw bytes.
async function readData(text, meta) {
  const raw = decodeBase64(text);
  if (meta.compression !== 'deflate') return raw;
  if (typeof DecompressionStream === 'undefined') throw new Error('this browser has no DecompressionStream');
  const stream = new Blob([raw]).stream().pipeThrough(new DecompressionStream('deflate'));
  const bytes = await new Response(stream).arrayBuffer();
  if (bytes.byteLength !== meta.bytes) throw new Error('the embedded model is damaged');
  return bytes;
}

// "#mode=ih" or "?mode=ih" (also "ih-mapping", "color"), else null.
function modeFromUrl() {
  const read = (s) => {
    const m = /(?:^|[?#&])mode=([a-z-]+)/.exec(s);
    if (!m) return null;
    const aliases = { color: 'colour', 'ih-mapping': 'ih' };
    const name = aliases[m[1]] || m[1];
    return MODES.includes(name) ? name : null;
  };
  return read(location.hash) || read(location.search);
}

// "#view=full" or "?view=full": the view opens filling the window.
function fullFromUrl() {
  return /(?:^|[?#&])view=full(?:$|&)/.test(location.hash) || /(?:^|[?#&])view=full(?:$|&)/.test(location.search);
}

const vertexShader = `
attribute vec3 colour;
attribute float unobserved;
varying vec3 vColour;
varying vec3 vNormal;
varying vec3 vToEye;
varying float vUnobserved;
vec3 srgbToLinear(vec3 c) {
  return mix(c / 12.92, pow((c + 0.055) / 1.055, vec3(2.4)), step(vec3(0.04045), c));
}
void main() {
  vec4 viewPosition = modelViewMatrix * vec4(position, 1.0);
  vToEye = -viewPosition.xyz;
  vNormal = normalMatrix * normal;
  vColour = srgbToLinear(colour);  // interpolated in linear light, like the images' blending
  vUnobserved = unobserved;
  gl_Position = projectionMatrix * viewPosition;
}`;

// The hatch is analyze::UnobservedHatchGrey: a mid grey with 1.5 px darker diagonal lines.
const fragmentShader = `
uniform float ambient;
uniform float diffuse;
uniform float hatch;
uniform float hatchPeriod;
varying vec3 vColour;
varying vec3 vNormal;
varying vec3 vToEye;
varying float vUnobserved;
float srgbToLinear1(float c) { return c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4); }
vec3 linearToSrgb(vec3 c) {
  c = clamp(c, 0.0, 1.0);
  return mix(12.92 * c, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), c));
}
void main() {
  vec3 n = normalize(vNormal);
  float cosIncidence = abs(dot(n, normalize(vToEye)));
  float shading = ambient + diffuse * cosIncidence;
  vec3 base = vColour;
  if (hatch > 0.5 && vUnobserved > 0.5) {
    float along = mod(gl_FragCoord.x + gl_FragCoord.y, hatchPeriod);
    float distancePx = min(along, hatchPeriod - along) / sqrt(2.0);
    float coverage = clamp(1.25 - distancePx, 0.0, 1.0);
    base = vec3(mix(srgbToLinear1(0.62), srgbToLinear1(0.40), coverage));
  }
  gl_FragColor = vec4(linearToSrgb(base * shading), 1.0);
}`;

function markerTexture(label, hot) {
  const canvas = document.createElement('canvas');
  canvas.width = 256;
  canvas.height = 128;
  const ctx = canvas.getContext('2d');
  ctx.fillStyle = hot ? 'rgba(200,30,30,0.9)' : 'rgba(30,80,220,0.9)';
  ctx.strokeStyle = 'white';
  ctx.lineWidth = 6;
  ctx.beginPath();
  ctx.arc(64, 64, 40, 0, 2 * Math.PI);
  ctx.fill();
  ctx.stroke();
  ctx.font = 'bold 44px sans-serif';
  ctx.textBaseline = 'middle';
  ctx.lineWidth = 8;
  ctx.strokeStyle = 'rgba(0,0,0,0.85)';
  // fillText draws the label as text: nothing in it is ever parsed as markup.
  const text = label.length > 12 ? label.slice(0, 11) + '…' : label;
  ctx.strokeText(text, 112, 64, 140);
  ctx.fillStyle = 'white';
  ctx.fillText(text, 112, 64, 140);
  const texture = new THREE.CanvasTexture(canvas);
  texture.colorSpace = THREE.SRGBColorSpace;
  return texture;
}

function fail(container, canvas, reason) {
  document.documentElement.dataset.hwViewer = 'failed';
  if (canvas) canvas.style.display = 'none';
  for (const e of container.querySelectorAll('.hw-viewer-modes, .hw-viewer-hint')) e.style.display = 'none';
  const message = container.querySelector('.hw-viewer-message');
  if (message) {
    message.textContent = 'The 3D view could not be shown (' + reason +
        '). The images in this report show the same model.';
    message.hidden = false;
  }
}

async function setUp(container) {
  const meta = JSON.parse(container.querySelector('script.hw-viewer-meta').textContent);
  const canvas = container.querySelector('canvas');
  let renderer;
  try {
    renderer = new THREE.WebGLRenderer({ canvas, antialias: true, alpha: true });
  } catch (e) {
    fail(container, canvas, 'WebGL is not available');
    return;
  }
  renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
  renderer.setClearColor(0x000000, 0);  // the container's CSS background shows through

  const bytes = await readData(container.querySelector('script.hw-viewer-data').textContent, meta);
  const o = meta.offsets;
  const quantised = new Uint16Array(bytes.slice(o.positions, o.positions + meta.vertices * 6));
  const min = meta.box_min, max = meta.box_max;
  const positions = new Float32Array(meta.vertices * 3);
  for (let i = 0; i < positions.length; ++i) {
    const a = i % 3;
    positions[i] = min[a] + (quantised[i] / 65535) * (max[a] - min[a]);
  }
  const indexBytes = meta.index32 ? 4 : 2;
  const indexSlice = bytes.slice(o.indices, o.indices + meta.faces * 3 * indexBytes);
  const indices = meta.index32 ? new Uint32Array(indexSlice) : new Uint16Array(indexSlice);

  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute('position', new THREE.BufferAttribute(positions, 3));
  geometry.setIndex(new THREE.BufferAttribute(indices, 1));
  geometry.computeVertexNormals();
  const colours = {};
  MODES.forEach((mode, k) => {
    const start = o.colours + k * meta.vertices * 3;
    colours[mode] = new THREE.BufferAttribute(
        new Uint8Array(bytes.slice(start, start + meta.vertices * 3)), 3, true);
  });
  const unobserved = new Uint8Array(bytes.slice(o.unobserved, o.unobserved + meta.vertices));
  geometry.setAttribute('unobserved', new THREE.BufferAttribute(unobserved, 1, true));

  const material = new THREE.ShaderMaterial({
    vertexShader,
    fragmentShader,
    side: THREE.DoubleSide,
    uniforms: {
      ambient: { value: meta.ambient },
      diffuse: { value: meta.diffuse },
      hatch: { value: 1 },
      hatchPeriod: { value: meta.hatch_period_px * renderer.getPixelRatio() },
    },
  });
  const scene = new THREE.Scene();
  const model = new THREE.Mesh(geometry, material);
  scene.add(model);

  // Framing: look at the box centre from `eye_direction` (chosen by the C++ side from the
  // model's frame), from the nearest distance at which all 8 box corners fit the view less
  // an 8 % margin (tighter than the bounding sphere for a flat wall).
  const centre = new THREE.Vector3((min[0] + max[0]) / 2, (min[1] + max[1]) / 2, (min[2] + max[2]) / 2);
  const diagonal = Math.hypot(max[0] - min[0], max[1] - min[1], max[2] - min[2]) || 1;
  const fovDeg = 40;
  const camera = new THREE.PerspectiveCamera(fovDeg, 1, diagonal * 1e-3, diagonal * 20);
  camera.up.set(meta.up[0], meta.up[1], meta.up[2]);
  const eye = new THREE.Vector3(meta.eye_direction[0], meta.eye_direction[1], meta.eye_direction[2]).normalize();
  const aspect = Math.max(1, canvas.clientWidth) / Math.max(1, canvas.clientHeight);
  const right = new THREE.Vector3().crossVectors(eye, camera.up).negate().normalize();
  const screenUp = new THREE.Vector3().crossVectors(right, eye).negate().normalize();
  const tanV = Math.tan(THREE.MathUtils.degToRad(fovDeg / 2)) * 0.92;
  const tanH = tanV * aspect;
  let distance = diagonal * 0.1;
  for (let k = 0; k < 8; ++k) {
    const corner = new THREE.Vector3(k & 1 ? max[0] : min[0], k & 2 ? max[1] : min[1], k & 4 ? max[2] : min[2]).sub(centre);
    const toward = corner.dot(eye);  // how much nearer the eye than the centre
    distance = Math.max(distance, toward + Math.abs(corner.dot(right)) / tanH,
                        toward + Math.abs(corner.dot(screenUp)) / tanV);
  }
  camera.position.copy(centre).addScaledVector(eye, distance);
  camera.lookAt(centre);

  const markerSize = diagonal * 0.05;
  const sprites = [];
  for (const m of meta.markers) {
    const sprite = new THREE.Sprite(new THREE.SpriteMaterial({ map: markerTexture(m.label, m.hot), depthTest: false }));
    sprite.center.set(0.25, 0.5);  // the disc (left quarter of the texture) sits on the spot
    sprite.scale.set(markerSize * 2, markerSize, 1);
    sprite.position.set(m.position[0] + m.normal[0] * markerSize * 0.3,
                        m.position[1] + m.normal[1] * markerSize * 0.3,
                        m.position[2] + m.normal[2] * markerSize * 0.3);
    sprite.renderOrder = 1;
    sprite.userData.anchor = m.anchor;
    scene.add(sprite);
    sprites.push(sprite);
  }

  const controls = new OrbitControls(camera, canvas);
  controls.target.copy(centre);
  controls.enableDamping = false;
  controls.update();

  let pending = false;
  let firstFrame = true;
  const draw = () => {
    pending = false;
    renderer.render(scene, camera);
    if (firstFrame) {
      firstFrame = false;
      const gl = renderer.getContext();
      if (gl.isContextLost()) {
        fail(container, canvas, 'the WebGL context was lost');
        return;
      }
      document.documentElement.dataset.hwViewer = 'rendered';
    }
  };
  const requestDraw = () => {
    if (!pending) {
      pending = true;
      requestAnimationFrame(draw);
    }
  };
  controls.addEventListener('change', requestDraw);

  const resize = () => {
    const width = Math.max(1, canvas.clientWidth);
    const height = Math.max(1, canvas.clientHeight);
    renderer.setSize(width, height, false);
    camera.aspect = width / height;
    camera.updateProjectionMatrix();
    requestDraw();
  };
  new ResizeObserver(resize).observe(canvas);
  window.addEventListener('resize', resize);

  const buttons = container.querySelectorAll('button[data-mode]');
  const setMode = (mode) => {
    if (!MODES.includes(mode) || !meta.modes.includes(mode)) return;
    geometry.setAttribute('colour', colours[mode]);
    material.uniforms.hatch.value = mode === 'colour' ? 0 : 1;
    buttons.forEach((b) => {
      const active = b.dataset.mode === mode;
      b.classList.toggle('hw-active', active);
      b.setAttribute('aria-pressed', active ? 'true' : 'false');
    });
    container.dataset.mode = mode;
    requestDraw();
  };
  buttons.forEach((b) => b.addEventListener('click', () => setMode(b.dataset.mode)));
  // Full window: the view covers the page until toggled back or Escape.
  const fullButton = container.querySelector('button[data-action="full"]');
  const setFull = (full) => {
    container.classList.toggle('hw-full', full);
    if (fullButton) fullButton.setAttribute('aria-pressed', full ? 'true' : 'false');
    resize();
  };
  if (fullButton) fullButton.addEventListener('click', () => setFull(!container.classList.contains('hw-full')));
  window.addEventListener('keydown', (e) => {
    if (e.key === 'Escape' && container.classList.contains('hw-full')) setFull(false);
  });
  if (fullFromUrl()) setFull(true);
  setMode(modeFromUrl() || meta.initial_mode);
  window.addEventListener('hashchange', () => {
    const mode = modeFromUrl();
    if (mode) setMode(mode);
  });

  // A click (not a drag) on a marker goes to its section. Markers are drawn over the
  // surface (no depth test), so a spot on a room's inner wall is found from outside too.
  const raycaster = new THREE.Raycaster();
  let down = null;
  canvas.addEventListener('pointerdown', (e) => { down = [e.clientX, e.clientY]; });
  canvas.addEventListener('pointerup', (e) => {
    if (!down || Math.hypot(e.clientX - down[0], e.clientY - down[1]) > 4) return;
    const rect = canvas.getBoundingClientRect();
    const ndc = new THREE.Vector2(((e.clientX - rect.left) / rect.width) * 2 - 1,
                                  -((e.clientY - rect.top) / rect.height) * 2 + 1);
    raycaster.setFromCamera(ndc, camera);
    const hits = raycaster.intersectObjects(sprites, false);
    if (hits.length > 0) location.hash = '#' + hits[0].object.userData.anchor;
  });
  canvas.addEventListener('pointermove', (e) => {
    if (e.buttons) return;
    const rect = canvas.getBoundingClientRect();
    raycaster.setFromCamera(new THREE.Vector2(((e.clientX - rect.left) / rect.width) * 2 - 1,
                                              -((e.clientY - rect.top) / rect.height) * 2 + 1), camera);
    canvas.style.cursor = raycaster.intersectObjects(sprites, false).length > 0 ? 'pointer' : '';
  });

  resize();
}

function start() {
  countCspViolations();
  for (const container of document.querySelectorAll('div.hw-viewer:not([data-hw-started])')) {
    container.dataset.hwStarted = '1';
    setUp(container).catch((e) => {
      fail(container, container.querySelector('canvas'), String(e && e.message ? e.message : e));
    });
  }
}

if (document.readyState === 'loading') {
  document.addEventListener('DOMContentLoaded', start);
} else {
  start();
}
