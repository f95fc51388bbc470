// The WebGL 2 renderer of host-tools' preview page (inlined into the page; no library).
//
// Printing moves are instances of one small tube mesh: the vertex shader places a ring of
// `sides` vertices around each end of the move (a stadium cross-section of the bead's width and
// height: flat-ish top and bottom, semicircular sides), mitred with the neighbouring move when
// the two join, and a cap where they do not. Normals are the cross-section's own, so lighting
// shows each bead's roundness, a wall's ripples and the grooves between layers. Travels and the
// bed are lines. A layer range is one contiguous range of instances (moves are in file order,
// layers never decrease), drawn by moving the attribute pointers — no copy. Picking draws ids
// into an off-screen buffer, only around the pointer (scissor), and reads them back.

// Per instance, floats: start xyz, start-ring width, end xyz, end-ring width, height, flags
// (1 joined to the previous move, 2 joined to the next). Instance 0 and the last are padding, so
// the previous/next attributes (same buffer, one instance back/ahead) always exist.
const TUBE_STRIDE = 10;

// The colour ramp: blue → cyan → green → yellow → red (as the legend's).
const RAMP_GLSL = `vec3 ramp(float u) {
  u = clamp(u, 0.0, 1.0) * 4.0;
  vec3 c0 = vec3(0.0, 0.157, 0.784), c1 = vec3(0.0, 0.745, 0.863), c2 = vec3(0.118, 0.706, 0.157);
  vec3 c3 = vec3(0.941, 0.784, 0.0), c4 = vec3(0.863, 0.118, 0.078);
  if (u < 1.0) return mix(c0, c1, u);
  if (u < 2.0) return mix(c1, c2, u - 1.0);
  if (u < 3.0) return mix(c2, c3, u - 2.0);
  return mix(c3, c4, u - 3.0);
}`;

const TUBE_VS = `#version 300 es
precision highp float;
precision highp int;
layout(location=0) in vec3 a_cs;   // cos, sin of the ring vertex; ring (see tubeMesh)
layout(location=1) in vec4 i_a;    // start, start-ring width
layout(location=2) in vec4 i_b;    // end, end-ring width
layout(location=3) in vec2 i_hf;   // height, join flags
layout(location=4) in vec3 i_pa;   // previous instance's start
layout(location=5) in vec3 i_nb;   // next instance's end
layout(location=6) in float i_v;   // colour value
uniform mat4 u_mvp;
uniform mat4 u_view;
uniform vec2 u_range;
uniform int u_plain;
uniform int u_base;
uniform int u_count;
uniform int u_hover;
uniform float u_expand;
out vec3 v_col;
out vec3 v_nrm;
flat out vec4 v_id;
${RAMP_GLSL}
void main() {
  float ring = a_cs.z;
  bool atEnd = mod(ring, 2.0) > 0.5;
  bool capRing = ring > 1.5 && ring < 3.5, centre = ring > 3.5;
  vec3 A = i_a.xyz, B = i_b.xyz;
  vec3 d = B - A;
  float len = length(d);
  vec3 t = len > 1e-6 ? d / len : vec3(1.0, 0.0, 0.0);
  int fl = int(i_hf.y + 0.5);
  // The first and last instance drawn end open (their neighbour is outside the layer range).
  bool joined = atEnd ? ((fl & 2) != 0 && gl_InstanceID < u_count - 1)
                      : ((fl & 1) != 0 && gl_InstanceID > 0);
  vec3 P = atEnd ? B : A;
  vec3 tc = t;
  if (joined) {
    vec3 o = atEnd ? i_nb - B : A - i_pa;
    float ol = length(o);
    if (ol > 1e-6) tc = normalize(t + o / ol);
  }
  float w = atEnd ? i_b.w : i_a.w;
  float h = i_hf.x;
  P.z -= 0.5 * h;   // the nozzle is at the top of the bead
  vec3 sway = cross(tc, vec3(0.0, 0.0, 1.0));
  float sl = length(sway);
  sway = sl > 1e-4 ? sway / sl : vec3(1.0, 0.0, 0.0);
  vec3 heave = cross(sway, tc);
  vec3 pos, nrm;
  if ((capRing || centre) && joined) {
    pos = P;      // no cap where the bead goes on
    nrm = t;
  } else if (centre) {
    float dir = atEnd ? 1.0 : -1.0;
    pos = P + t * (dir * 0.5 * w);
    nrm = t * dir;
  } else {
    float c = a_cs.x, s = a_cs.y;
    float miter = 1.0 / max(dot(tc, t), 0.5);
    float straight = max(w - h, 0.0) * 0.5;
    pos = P + sway * (miter * (sign(c) * straight + c * u_expand * 0.5 * h))
            + heave * (s * u_expand * 0.5 * h);
    nrm = sway * c + heave * s;
  }
  gl_Position = u_mvp * vec4(pos, 1.0);
  v_nrm = mat3(u_view) * nrm;
  int id = u_base + gl_InstanceID;
  vec3 col = u_plain == 1 ? vec3(0.93, 0.56, 0.2)
                          : ramp((i_v - u_range.x) / max(u_range.y - u_range.x, 1e-9));
  if (id == u_hover) col = mix(col, vec3(1.0), 0.7);
  v_col = col;
  int k = id + 1;
  v_id = vec4(float(k & 255), float((k >> 8) & 255), float((k >> 16) & 255), 255.0) / 255.0;
}`;

const TUBE_FS = `#version 300 es
precision highp float;
in vec3 v_col;
in vec3 v_nrm;
flat in vec4 v_id;
uniform int u_pick;
out vec4 o_col;
void main() {
  if (u_pick == 1) { o_col = v_id; return; }
  vec3 n = normalize(v_nrm);
  // A key light from the upper left of the viewer, a weak fill from the lower right.
  vec3 key = normalize(vec3(-0.35, 0.6, 0.72));
  vec3 fill = normalize(vec3(0.6, -0.4, 0.7));
  float diff = max(dot(n, key), 0.0);
  float spec = pow(max(dot(n, normalize(key + vec3(0.0, 0.0, 1.0))), 0.0), 32.0);
  vec3 c = v_col * (0.22 + 0.68 * diff + 0.18 * max(dot(n, fill), 0.0)) + vec3(0.25 * spec);
  o_col = vec4(min(c, vec3(1.0)), 1.0);
}`;

const LINE_VS = `#version 300 es
precision highp float;
precision highp int;
layout(location=0) in vec3 a_pos;
layout(location=6) in float a_v;   // colour value (printing moves drawn as lines)
uniform mat4 u_mvp;
uniform int u_base;
uniform int u_hover;
uniform int u_ramp;
uniform vec2 u_range;
uniform vec3 u_color;
out vec3 v_col;
flat out vec4 v_id;
${RAMP_GLSL}
void main() {
  gl_Position = u_mvp * vec4(a_pos, 1.0);
  int id = u_base + gl_VertexID / 2;
  vec3 col = u_ramp == 1 ? ramp((a_v - u_range.x) / max(u_range.y - u_range.x, 1e-9)) : u_color;
  v_col = id == u_hover ? vec3(0.1, 0.1, 0.1) : col;
  int k = id + 1;
  v_id = vec4(float(k & 255), float((k >> 8) & 255), float((k >> 16) & 255), 255.0) / 255.0;
}`;

const LINE_FS = `#version 300 es
precision highp float;
in vec3 v_col;
flat in vec4 v_id;
uniform int u_pick;
out vec4 o_col;
void main() { o_col = u_pick == 1 ? v_id : vec4(v_col, 1.0); }`;

// The tube mesh of `sides` (a multiple of 4) around: angles start half a step off the axes so
// no vertex sits exactly on the stadium's flat top.
function tubeMesh(gl, sides) {
  const v = [];
  // Rings: 0 start and 1 end (the sides), 2 and 3 their copies for the caps; 4 and 5 the cap
  // centres. A joined end collapses its cap (copies and centre) to one point: no area to draw.
  for (let ring = 0; ring < 4; ring++) {
    for (let k = 0; k < sides; k++) {
      const a = (k + 0.5) * 2 * Math.PI / sides;
      v.push(Math.cos(a), Math.sin(a), ring);
    }
  }
  v.push(0, 0, 4, 0, 0, 5);
  const idx = [], c0 = 4 * sides, c1 = 4 * sides + 1;
  for (let k = 0; k < sides; k++) {
    const k1 = (k + 1) % sides;
    idx.push(k, k1, sides + k, k1, sides + k1, sides + k);
    idx.push(c0, 2 * sides + k1, 2 * sides + k, c1, 3 * sides + k, 3 * sides + k1);
  }
  const vb = gl.createBuffer();
  gl.bindBuffer(gl.ARRAY_BUFFER, vb);
  gl.bufferData(gl.ARRAY_BUFFER, new Float32Array(v), gl.STATIC_DRAW);
  const ib = gl.createBuffer();
  gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, ib);
  gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, new Uint16Array(idx), gl.STATIC_DRAW);
  // Vertices half a step off the axes: scaled by 1/cos(π/sides), the polygon's flats touch
  // the bead's true width and height.
  return { vb, ib, count: idx.length, expand: 1 / Math.cos(Math.PI / sides) };
}

function compile(gl, vs, fs) {
  const p = gl.createProgram();
  for (const [type, src] of [[gl.VERTEX_SHADER, vs], [gl.FRAGMENT_SHADER, fs]]) {
    const s = gl.createShader(type);
    gl.shaderSource(s, src);
    gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
    gl.attachShader(p, s);
  }
  gl.linkProgram(p);
  if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(p));
  const u = {};
  const n = gl.getProgramParameter(p, gl.ACTIVE_UNIFORMS);
  for (let i = 0; i < n; i++) {
    const name = gl.getActiveUniform(p, i).name;
    u[name] = gl.getUniformLocation(p, name);
  }
  return { p, u };
}

// Returns null when the browser has no WebGL 2.
function makeRenderer(canvas) {
  const gl = canvas.getContext("webgl2", { antialias: true, preserveDrawingBuffer: true });
  if (!gl) return null;
  const tube = compile(gl, TUBE_VS, TUBE_FS);
  const line = compile(gl, LINE_VS, LINE_FS);
  const meshes = { fine: tubeMesh(gl, 8), coarse: tubeMesh(gl, 4) };
  const vao = gl.createVertexArray();
  const buf = { inst: gl.createBuffer(), val: gl.createBuffer(), travel: gl.createBuffer(),
                bed: gl.createBuffer(), tubeLines: gl.createBuffer(), lineVal: gl.createBuffer() };
  let nTubes = 0, nTravels = 0, nBed = 0;
  const pick = { fbo: gl.createFramebuffer(), col: gl.createRenderbuffer(),
                 depth: gl.createRenderbuffer(), w: 0, h: 0 };

  function lineBuffer(b, data) {
    gl.bindBuffer(gl.ARRAY_BUFFER, b);
    gl.bufferData(gl.ARRAY_BUFFER, data, gl.STATIC_DRAW);
    return data.length / 3;
  }

  // Points the instance attributes at instances [first, first + count) of the tube buffer.
  function bindTubes(mesh, first) {
    gl.bindVertexArray(vao);
    gl.bindBuffer(gl.ARRAY_BUFFER, mesh.vb);
    gl.enableVertexAttribArray(0);
    gl.vertexAttribPointer(0, 3, gl.FLOAT, false, 0, 0);
    gl.vertexAttribDivisor(0, 0);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, mesh.ib);
    const S = TUBE_STRIDE * 4, j = (first + 1) * S;
    gl.bindBuffer(gl.ARRAY_BUFFER, buf.inst);
    for (const [loc, size, off] of [[1, 4, j], [2, 4, j + 16], [3, 2, j + 32], [4, 3, j - S],
                                    [5, 3, j + S + 16]]) {
      gl.enableVertexAttribArray(loc);
      gl.vertexAttribPointer(loc, size, gl.FLOAT, false, S, off);
      gl.vertexAttribDivisor(loc, 1);
    }
    gl.bindBuffer(gl.ARRAY_BUFFER, buf.val);
    gl.enableVertexAttribArray(6);
    gl.vertexAttribPointer(6, 1, gl.FLOAT, false, 4, first * 4);
    gl.vertexAttribDivisor(6, 1);
  }

  // Lines from buffer `b` (two points per line), coloured by `values` (one per point) or not.
  function bindLines(b, values) {
    gl.bindVertexArray(vao);
    for (let loc = 1; loc <= 6; loc++) gl.disableVertexAttribArray(loc);
    gl.bindBuffer(gl.ARRAY_BUFFER, b);
    gl.enableVertexAttribArray(0);
    gl.vertexAttribPointer(0, 3, gl.FLOAT, false, 0, 0);
    gl.vertexAttribDivisor(0, 0);
    if (values) {
      gl.bindBuffer(gl.ARRAY_BUFFER, values);
      gl.enableVertexAttribArray(6);
      gl.vertexAttribPointer(6, 1, gl.FLOAT, false, 0, 0);
      gl.vertexAttribDivisor(6, 0);
    } else {
      gl.vertexAttrib1f(6, 0);
    }
  }

  // f: { mvp, view, tubes: [first, count], travels: [first, count] | null, range: [lo, hi],
  //      plain, hover (id or -1), coarse, lines, pick }
  function render(f) {
    if (f.tubes[1] > 0 && f.lines) {
      // Printing moves as lines (a slow renderer while the view turns).
      gl.useProgram(line.p);
      gl.uniformMatrix4fv(line.u.u_mvp, false, f.mvp);
      gl.uniform1i(line.u.u_hover, f.hover);
      gl.uniform1i(line.u.u_pick, f.pick ? 1 : 0);
      gl.uniform1i(line.u.u_base, 0);
      gl.uniform1i(line.u.u_ramp, f.plain ? 0 : 1);
      gl.uniform2f(line.u.u_range, f.range[0], f.range[1]);
      gl.uniform3f(line.u.u_color, 0.93, 0.56, 0.2);
      bindLines(buf.tubeLines, buf.lineVal);
      gl.drawArrays(gl.LINES, 2 * f.tubes[0], 2 * f.tubes[1]);
    } else if (f.tubes[1] > 0) {
      const mesh = f.coarse ? meshes.coarse : meshes.fine;
      gl.useProgram(tube.p);
      gl.uniformMatrix4fv(tube.u.u_mvp, false, f.mvp);
      gl.uniformMatrix4fv(tube.u.u_view, false, f.view);
      gl.uniform2f(tube.u.u_range, f.range[0], f.range[1]);
      gl.uniform1i(tube.u.u_plain, f.plain ? 1 : 0);
      gl.uniform1i(tube.u.u_base, f.tubes[0]);
      gl.uniform1i(tube.u.u_count, f.tubes[1]);
      gl.uniform1i(tube.u.u_hover, f.hover);
      gl.uniform1i(tube.u.u_pick, f.pick ? 1 : 0);
      gl.uniform1f(tube.u.u_expand, mesh.expand);
      bindTubes(mesh, f.tubes[0]);
      gl.drawElementsInstanced(gl.TRIANGLES, mesh.count, gl.UNSIGNED_SHORT, 0, f.tubes[1]);
    }
    gl.useProgram(line.p);
    gl.uniformMatrix4fv(line.u.u_mvp, false, f.mvp);
    gl.uniform1i(line.u.u_hover, f.hover);
    gl.uniform1i(line.u.u_pick, f.pick ? 1 : 0);
    gl.uniform1i(line.u.u_ramp, 0);
    if (f.travels && f.travels[1] > 0) {
      bindLines(buf.travel);
      gl.uniform1i(line.u.u_base, nTubes);
      gl.uniform3f(line.u.u_color, 0.5, 0.5, 0.56);
      gl.drawArrays(gl.LINES, 2 * f.travels[0], 2 * f.travels[1]);
    }
    if (!f.pick && nBed > 0) {
      bindLines(buf.bed);
      gl.uniform1i(line.u.u_base, -1000000000);
      gl.uniform3f(line.u.u_color, 0.72, 0.72, 0.72);
      gl.drawArrays(gl.LINES, 0, nBed);
    }
    gl.bindVertexArray(null);
  }

  return {
    gl,
    // inst: Float32Array of (n + 2) × TUBE_STRIDE; points: the same n moves as lines (two
    // points each).
    setTubes(inst, n, points) {
      nTubes = n;
      gl.bindBuffer(gl.ARRAY_BUFFER, buf.inst);
      gl.bufferData(gl.ARRAY_BUFFER, inst, gl.STATIC_DRAW);
      lineBuffer(buf.tubeLines, points);
      this.setValues(new Float32Array(Math.max(1, n)));
    },
    // The colour value of each tube.
    setValues(values) {
      gl.bindBuffer(gl.ARRAY_BUFFER, buf.val);
      gl.bufferData(gl.ARRAY_BUFFER, values, gl.DYNAMIC_DRAW);
      const twice = new Float32Array(2 * values.length);
      for (let j = 0; j < values.length; j++) twice[2 * j] = twice[2 * j + 1] = values[j];
      gl.bindBuffer(gl.ARRAY_BUFFER, buf.lineVal);
      gl.bufferData(gl.ARRAY_BUFFER, twice, gl.DYNAMIC_DRAW);
    },
    // Two points per travel.
    setTravels(points) { nTravels = lineBuffer(buf.travel, points) / 2; },
    setBed(points) { nBed = lineBuffer(buf.bed, points); },
    tubeCount() { return nTubes; },
    travelCount() { return nTravels; },
    draw(f) {
      const w = canvas.width, h = canvas.height;
      gl.bindFramebuffer(gl.FRAMEBUFFER, null);
      gl.viewport(0, 0, w, h);
      gl.disable(gl.SCISSOR_TEST);
      gl.enable(gl.DEPTH_TEST);
      gl.clearColor(1, 1, 1, 1);
      gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
      render(Object.assign({}, f, { pick: false }));
    },
    // The id (0-based; tubes first, then travels) drawn nearest to device pixel (x, y) within
    // a 7 × 7 square, or -1.
    pick(f, x, y) {
      const w = canvas.width, h = canvas.height;
      if (pick.w !== w || pick.h !== h) {
        gl.bindRenderbuffer(gl.RENDERBUFFER, pick.col);
        gl.renderbufferStorage(gl.RENDERBUFFER, gl.RGBA8, w, h);
        gl.bindRenderbuffer(gl.RENDERBUFFER, pick.depth);
        gl.renderbufferStorage(gl.RENDERBUFFER, gl.DEPTH_COMPONENT24, w, h);
        gl.bindFramebuffer(gl.FRAMEBUFFER, pick.fbo);
        gl.framebufferRenderbuffer(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.RENDERBUFFER, pick.col);
        gl.framebufferRenderbuffer(gl.FRAMEBUFFER, gl.DEPTH_ATTACHMENT, gl.RENDERBUFFER, pick.depth);
        pick.w = w; pick.h = h;
      }
      // The pixel holding (x, y); its row counted from the bottom, as GL counts.
      const R = 3, px = Math.floor(x), py = Math.floor(h - y);
      const x0 = Math.max(0, px - R), y0 = Math.max(0, py - R);
      const x1 = Math.min(w, px + R + 1), y1 = Math.min(h, py + R + 1);
      if (x1 <= x0 || y1 <= y0) return -1;
      gl.bindFramebuffer(gl.FRAMEBUFFER, pick.fbo);
      gl.viewport(0, 0, w, h);
      gl.enable(gl.SCISSOR_TEST);
      gl.scissor(x0, y0, x1 - x0, y1 - y0);
      gl.enable(gl.DEPTH_TEST);
      gl.clearColor(0, 0, 0, 0);
      gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
      render(Object.assign({}, f, { pick: true, hover: -1 }));
      const px4 = new Uint8Array(4 * (x1 - x0) * (y1 - y0));
      gl.readPixels(x0, y0, x1 - x0, y1 - y0, gl.RGBA, gl.UNSIGNED_BYTE, px4);
      gl.disable(gl.SCISSOR_TEST);
      gl.bindFramebuffer(gl.FRAMEBUFFER, null);
      let best = -1, bestD = Infinity;
      for (let j = 0; j < y1 - y0; j++) {
        for (let i = 0; i < x1 - x0; i++) {
          const o = 4 * (j * (x1 - x0) + i);
          const id = px4[o] + 256 * px4[o + 1] + 65536 * px4[o + 2];
          const d = (x0 + i - px) ** 2 + (y0 + j - py) ** 2;
          if (id > 0 && d < bestD) { best = id - 1; bestD = d; }
        }
      }
      return best;
    },
    // Waits for the GPU (for frame-time measurements only).
    finish() { const p = new Uint8Array(4); gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, p); },
  };
}
