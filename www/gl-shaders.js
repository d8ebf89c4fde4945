// Shader sources of the map view and the one helper that builds them:
// round splats for the surfels (colour by RGB / normal / confidence, absorbed
// surfels hidden) and flat-colour lines for the trajectories and the frustum.
// Used by renderer.js.

/** Colour modes of the surfel shader's uMode. */
export const MODES = { rgb: 0, normal: 1, confidence: 2 };

export const SURFEL_VS = `#version 300 es
layout(location = 0) in vec3 aPosition;
layout(location = 1) in vec3 aNormal;
layout(location = 2) in vec4 aColour;
layout(location = 3) in float aRadius;
layout(location = 4) in float aConfidence;
uniform mat4 uView;
uniform mat4 uProj;
uniform float uPixelsPerUnit;   // viewport height / (2 tan(fovy/2))
uniform float uSizeScale;
uniform float uMaxPointSize;
uniform float uConfidenceMax;
uniform int uMode;              // 0 rgb, 1 normal, 2 confidence
out vec3 vColour;

vec3 turbo(float x) {
  x = clamp(x, 0.0, 1.0);
  vec4 kR = vec4(0.13572138, 4.61539260, -42.66032258, 132.13108234);
  vec4 kG = vec4(0.09140261, 2.19418839, 4.84296658, -14.18503333);
  vec4 kB = vec4(0.10667330, 12.64194608, -60.58204836, 110.36276771);
  vec2 kR2 = vec2(-152.94239396, 59.28637943);
  vec2 kG2 = vec2(4.27729857, 2.82956604);
  vec2 kB2 = vec2(-89.90310912, 27.34824973);
  vec4 v4 = vec4(1.0, x, x * x, x * x * x);
  vec2 v2 = v4.zw * v4.z;
  return vec3(dot(v4, kR) + dot(v2, kR2), dot(v4, kG) + dot(v2, kG2), dot(v4, kB) + dot(v2, kB2));
}

void main() {
  // Absorbed into another surfel (negative confidence): gone from the map at
  // the next compaction; hidden as soon as its confidence reaches the GPU.
  if (aConfidence < 0.0) {
    gl_Position = vec4(2.0, 2.0, 2.0, 1.0);
    gl_PointSize = 0.0;
    vColour = vec3(0.0);
    return;
  }
  vec4 eye = uView * vec4(aPosition, 1.0);
  gl_Position = uProj * eye;
  float z = max(-eye.z, 1e-3);
  gl_PointSize = clamp(2.0 * aRadius * uSizeScale * uPixelsPerUnit / z, 1.0, uMaxPointSize);
  if (uMode == 1) {
    vColour = normalize(aNormal) * 0.5 + 0.5;
  } else if (uMode == 2) {
    vColour = turbo(aConfidence / uConfidenceMax);
  } else {
    vColour = aColour.rgb;
  }
}`;

export const SURFEL_FS = `#version 300 es
precision mediump float;
in vec3 vColour;
out vec4 outColour;
void main() {
  vec2 c = gl_PointCoord * 2.0 - 1.0;
  float r2 = dot(c, c);
  if (r2 > 1.0) discard;
  outColour = vec4(vColour * (1.0 - 0.15 * r2), 1.0);
}`;

export const LINE_VS = `#version 300 es
layout(location = 0) in vec3 aPosition;
uniform mat4 uView;
uniform mat4 uProj;
void main() { gl_Position = uProj * uView * vec4(aPosition, 1.0); }`;

export const LINE_FS = `#version 300 es
precision mediump float;
uniform vec4 uColour;
out vec4 outColour;
void main() { outColour = uColour; }`;

/** Compiles and links a program; `uniforms` maps each active uniform's name to its location. */
export function compile(gl, vsSource, fsSource) {
  const program = gl.createProgram();
  for (const [type, source] of [
    [gl.VERTEX_SHADER, vsSource],
    [gl.FRAGMENT_SHADER, fsSource],
  ]) {
    const shader = gl.createShader(type);
    gl.shaderSource(shader, source);
    gl.compileShader(shader);
    if (!gl.getShaderParameter(shader, gl.COMPILE_STATUS)) throw new Error(`shader: ${gl.getShaderInfoLog(shader)}`);
    gl.attachShader(program, shader);
  }
  gl.linkProgram(program);
  if (!gl.getProgramParameter(program, gl.LINK_STATUS)) throw new Error(`program: ${gl.getProgramInfoLog(program)}`);
  const uniforms = {};
  const n = gl.getProgramParameter(program, gl.ACTIVE_UNIFORMS);
  for (let i = 0; i < n; i++) {
    const name = gl.getActiveUniform(program, i).name;
    uniforms[name] = gl.getUniformLocation(program, name);
  }
  return { program, uniforms };
}
