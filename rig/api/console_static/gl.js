// A point-cloud and mesh viewer in plain WebGL2: one buffer per attribute as the daemon sends them
// (rig.api.clouds: float32 positions, uint8 colours, int8 normals, uint8 quality), an orbit camera,
// colour by RGB, depth, normal, quality or (simulated rigs) error against the truth, and picking
// on the CPU (the nearest point on screen).

const VERTEX = `#version 300 es
in vec3 position; in vec3 color; in vec3 normal; in float quality; in float error;
uniform mat4 mvp; uniform mat4 view; uniform float pointSize; uniform int mode; uniform vec2 depthRange;
uniform float errorScale;
out vec3 vColor;
vec3 ramp(float t) {  // blue (far) to red (near), through green and yellow
  t = clamp(t, 0.0, 1.0);
  return clamp(vec3(1.5 - abs(4.0 * t - 3.0), 1.5 - abs(4.0 * t - 2.0), 1.5 - abs(4.0 * t - 1.0)), 0.0, 1.0);
}
void main() {
  gl_Position = mvp * vec4(position, 1.0);
  gl_PointSize = pointSize;
  if (mode == 0) vColor = color;
  else if (mode == 1) vColor = ramp(1.0 - (-(view * vec4(position, 1.0)).z - depthRange.x) / max(depthRange.y - depthRange.x, 1e-6));
  else if (mode == 2) vColor = normal * 0.5 + 0.5;
  else if (mode == 3) vColor = ramp(quality);
  else vColor = ramp(error / errorScale);  // against the simulator's truth: 0 blue, errorScale and more red
}`;

const FRAGMENT = `#version 300 es
precision mediump float;
in vec3 vColor; out vec4 outColor;
void main() { outColor = vec4(vColor, 1.0); }`;

export const MODES = { rgb: 0, depth: 1, normal: 2, quality: 3, error: 4 };

export function parseBody(buffer) {
  const length = new DataView(buffer).getUint32(0, true);
  const header = JSON.parse(new TextDecoder().decode(new Uint8Array(buffer, 4, length)));
  const base = 4 + length;
  const types = { float32: Float32Array, uint8: Uint8Array, int8: Int8Array, uint32: Uint32Array };
  const arrays = {};
  for (const a of header.arrays) arrays[a.name] = new types[a.type](buffer, base + a.offset, a.count * a.components);
  return { header, arrays };
}

export class Viewer {
  constructor(canvas) {
    this.canvas = canvas;
    const gl = canvas.getContext("webgl2", { antialias: false });
    if (!gl) throw new Error("this browser has no WebGL2");
    this.gl = gl;
    this.program = program(gl, VERTEX, FRAGMENT);
    this.mode = 0; this.pointSize = 2; this.marks = [];
    this.yaw = 0; this.pitch = 0; this.distance = 1; this.target = [0, 0, 0];
    this.cloud = null;
  }

  load({ header, arrays }) {
    const gl = this.gl;
    if (this.vao) gl.deleteVertexArray(this.vao);
    this.vao = gl.createVertexArray();
    gl.bindVertexArray(this.vao);
    const attribute = (name, data, size, type, normalized) => {
      const loc = gl.getAttribLocation(this.program, name);
      if (loc < 0) return;
      if (!data) { gl.disableVertexAttribArray(loc); gl.vertexAttrib4f(loc, 0.7, 0.7, 0.7, 1); return; }
      const buffer = gl.createBuffer();
      gl.bindBuffer(gl.ARRAY_BUFFER, buffer);
      gl.bufferData(gl.ARRAY_BUFFER, data, gl.STATIC_DRAW);
      gl.enableVertexAttribArray(loc);
      gl.vertexAttribPointer(loc, size, type, normalized, 0, 0);
    };
    attribute("position", arrays.position, 3, gl.FLOAT, false);
    attribute("color", arrays.color, 3, gl.UNSIGNED_BYTE, true);
    attribute("normal", arrays.normal, 3, gl.BYTE, true);
    attribute("quality", arrays.quality, 1, gl.UNSIGNED_BYTE, true);
    attribute("error", arrays.error, 1, gl.FLOAT, false);
    this.errorScale = Math.max(1e-3, 2 * (header.error_p95_mm || 0.5));
    this.count = header.points;
    this.triangles = arrays.triangles ? arrays.triangles.length : 0;
    if (arrays.triangles) {
      const index = gl.createBuffer();
      gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, index);
      gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, arrays.triangles, gl.STATIC_DRAW);
    }
    gl.bindVertexArray(null);
    this.cloud = { header, positions: arrays.position };
    if (header.bounds && !this.framed) this.frame(header.bounds);
    this.draw();
  }

  frame([low, high]) {
    this.target = low.map((v, i) => (v + high[i]) / 2);
    this.radius = Math.hypot(...low.map((v, i) => high[i] - v)) / 2 || 1;
    this.distance = this.radius * 2.6;
    this.yaw = 0; this.pitch = 0; this.framed = true;
  }

  matrices() {
    const aspect = this.canvas.width / this.canvas.height;
    const eye = [
      this.target[0] + this.distance * Math.cos(this.pitch) * Math.sin(this.yaw),
      this.target[1] - this.distance * Math.sin(this.pitch),
      this.target[2] - this.distance * Math.cos(this.pitch) * Math.cos(this.yaw),
    ];
    const view = lookAt(eye, this.target, [0, -1, 0]);  // the camera frame: y down, z into the scene
    const near = Math.max(this.distance - this.radius * 3, this.distance * 0.01);
    const projection = perspective(Math.PI / 4, aspect, near, this.distance + this.radius * 3);
    return { view, mvp: multiply(projection, view), depth: [this.distance - this.radius, this.distance + this.radius] };
  }

  draw() {
    const gl = this.gl;
    gl.viewport(0, 0, this.canvas.width, this.canvas.height);
    gl.clearColor(0.07, 0.09, 0.11, 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    if (!this.cloud) return;
    gl.enable(gl.DEPTH_TEST);
    gl.useProgram(this.program);
    const { view, mvp, depth } = this.matrices();
    const u = (name) => gl.getUniformLocation(this.program, name);
    gl.uniformMatrix4fv(u("mvp"), false, mvp);
    gl.uniformMatrix4fv(u("view"), false, view);
    gl.uniform1f(u("pointSize"), this.pointSize);
    gl.uniform1i(u("mode"), this.mode);
    gl.uniform2f(u("depthRange"), depth[0], depth[1]);
    gl.uniform1f(u("errorScale"), this.errorScale || 1);
    gl.bindVertexArray(this.vao);
    if (this.triangles && this.showMesh) gl.drawElements(gl.TRIANGLES, this.triangles, gl.UNSIGNED_INT, 0);
    else gl.drawArrays(gl.POINTS, 0, this.count);
    gl.bindVertexArray(null);
  }

  // The point drawn nearest to canvas pixel (x, y) within `radius` pixels (the front one), or null.
  pick(x, y, radius = 6) {
    if (!this.cloud) return null;
    const { mvp } = this.matrices();
    const p = this.cloud.positions, w = this.canvas.width, hgt = this.canvas.height;
    let best = null, bestScore = Infinity;
    for (let i = 0; i < p.length; i += 3) {
      const cx = mvp[0] * p[i] + mvp[4] * p[i + 1] + mvp[8] * p[i + 2] + mvp[12];
      const cy = mvp[1] * p[i] + mvp[5] * p[i + 1] + mvp[9] * p[i + 2] + mvp[13];
      const cw = mvp[3] * p[i] + mvp[7] * p[i + 1] + mvp[11] * p[i + 2] + mvp[15];
      if (cw <= 0) continue;
      const sx = ((cx / cw) * 0.5 + 0.5) * w, sy = (1 - ((cy / cw) * 0.5 + 0.5)) * hgt;
      const d2 = (sx - x) ** 2 + (sy - y) ** 2;
      if (d2 > radius * radius) continue;
      const score = cw + d2 * 1e-3 * this.distance;  // the front one, then the nearest on screen
      if (score < bestScore) { bestScore = score; best = [p[i], p[i + 1], p[i + 2]]; }
    }
    return best;
  }

  // Mouse and keyboard: drag orbits, shift-drag or right-drag pans, the wheel zooms; arrows and +/-.
  controls(onChange) {
    const c = this.canvas;
    let last = null;
    c.addEventListener("contextmenu", (e) => e.preventDefault());
    c.addEventListener("pointerdown", (e) => { last = [e.clientX, e.clientY, e.button === 2 || e.shiftKey]; this.moved = false; c.setPointerCapture(e.pointerId); });
    c.addEventListener("pointerup", () => { last = null; });
    c.addEventListener("pointermove", (e) => {
      if (!last) return;
      const dx = e.clientX - last[0], dy = e.clientY - last[1];
      if (Math.abs(dx) + Math.abs(dy) > 2) this.moved = true;
      if (last[2]) this.pan(dx, dy); else this.orbit(dx * 0.01, dy * 0.01);
      last = [e.clientX, e.clientY, last[2]];
      onChange();
    });
    c.addEventListener("wheel", (e) => { e.preventDefault(); this.zoom(Math.exp(e.deltaY * 0.001)); onChange(); }, { passive: false });
    c.addEventListener("keydown", (e) => {
      const keys = { ArrowLeft: () => this.orbit(-0.1, 0), ArrowRight: () => this.orbit(0.1, 0), ArrowUp: () => this.orbit(0, -0.1), ArrowDown: () => this.orbit(0, 0.1), "+": () => this.zoom(0.9), "=": () => this.zoom(0.9), "-": () => this.zoom(1.1) };
      if (keys[e.key]) { e.preventDefault(); keys[e.key](); onChange(); }
    });
  }

  orbit(yaw, pitch) { this.yaw += yaw; this.pitch = Math.max(-1.5, Math.min(1.5, this.pitch + pitch)); }
  zoom(factor) { this.distance = Math.max(this.radius * 0.05, this.distance * factor); }
  pan(dx, dy) {
    const scale = (this.distance * 0.0015);
    const right = [Math.cos(this.yaw), 0, Math.sin(this.yaw)];
    this.target = this.target.map((v, i) => v - right[i] * dx * scale);
    this.target[1] -= dy * scale;
  }
}

function program(gl, vs, fs) {
  const compile = (type, source) => {
    const shader = gl.createShader(type);
    gl.shaderSource(shader, source);
    gl.compileShader(shader);
    if (!gl.getShaderParameter(shader, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(shader));
    return shader;
  };
  const p = gl.createProgram();
  gl.attachShader(p, compile(gl.VERTEX_SHADER, vs));
  gl.attachShader(p, compile(gl.FRAGMENT_SHADER, fs));
  gl.linkProgram(p);
  if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(p));
  return p;
}

// Column-major 4x4 matrices, as WebGL takes them.
function perspective(fovy, aspect, near, far) {
  const f = 1 / Math.tan(fovy / 2), nf = 1 / (near - far);
  return new Float32Array([f / aspect, 0, 0, 0, 0, f, 0, 0, 0, 0, (far + near) * nf, -1, 0, 0, 2 * far * near * nf, 0]);
}

function lookAt(eye, target, up) {
  const z = normalize(eye.map((v, i) => v - target[i]));
  const x = normalize(cross(up, z));
  const y = cross(z, x);
  return new Float32Array([x[0], y[0], z[0], 0, x[1], y[1], z[1], 0, x[2], y[2], z[2], 0,
    -dot(x, eye), -dot(y, eye), -dot(z, eye), 1]);
}

function multiply(a, b) {
  const out = new Float32Array(16);
  for (let c = 0; c < 4; c++) for (let r = 0; r < 4; r++) {
    let s = 0;
    for (let k = 0; k < 4; k++) s += a[k * 4 + r] * b[c * 4 + k];
    out[c * 4 + r] = s;
  }
  return out;
}

const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
const normalize = (a) => { const n = Math.hypot(...a) || 1; return a.map((v) => v / n); };
