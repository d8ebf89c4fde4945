// Small column-major 4x4 matrix and vector helpers for the renderer (Float32/64 agnostic).

export const vec3 = {
  add: (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]],
  sub: (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]],
  scale: (a, s) => [a[0] * s, a[1] * s, a[2] * s],
  dot: (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2],
  cross: (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]],
  length: (a) => Math.hypot(a[0], a[1], a[2]),
  normalize(a) {
    const l = Math.hypot(a[0], a[1], a[2]) || 1;
    return [a[0] / l, a[1] / l, a[2] / l];
  },
};

export function identity() {
  const m = new Float64Array(16);
  m[0] = m[5] = m[10] = m[15] = 1;
  return m;
}

/** c = a * b (column-major). */
export function multiply(a, b) {
  const c = new Float64Array(16);
  for (let col = 0; col < 4; col++) {
    for (let row = 0; row < 4; row++) {
      let s = 0;
      for (let k = 0; k < 4; k++) s += a[k * 4 + row] * b[col * 4 + k];
      c[col * 4 + row] = s;
    }
  }
  return c;
}

/** Inverse of a rigid transform [R t; 0 1]. */
export function invertRigid(m) {
  const r = new Float64Array(16);
  for (let i = 0; i < 3; i++) for (let j = 0; j < 3; j++) r[j * 4 + i] = m[i * 4 + j];
  const t = [m[12], m[13], m[14]];
  for (let i = 0; i < 3; i++) r[12 + i] = -(r[i] * t[0] + r[4 + i] * t[1] + r[8 + i] * t[2]);
  r[15] = 1;
  return r;
}

/** Applies a 4x4 transform to a point. */
export function transformPoint(m, p) {
  return [
    m[0] * p[0] + m[4] * p[1] + m[8] * p[2] + m[12],
    m[1] * p[0] + m[5] * p[1] + m[9] * p[2] + m[13],
    m[2] * p[0] + m[6] * p[1] + m[10] * p[2] + m[14],
  ];
}

/** Column `i` (0..3) of the upper 3 rows. */
export const column = (m, i) => [m[i * 4], m[i * 4 + 1], m[i * 4 + 2]];

/** Pose matrix from a translation and a unit quaternion [x, y, z, w]. */
export function poseFromTq(t, q) {
  const [x, y, z, w] = q;
  const n = Math.hypot(x, y, z, w) || 1;
  const qx = x / n, qy = y / n, qz = z / n, qw = w / n;
  const m = identity();
  m[0] = 1 - 2 * (qy * qy + qz * qz);
  m[1] = 2 * (qx * qy + qz * qw);
  m[2] = 2 * (qx * qz - qy * qw);
  m[4] = 2 * (qx * qy - qz * qw);
  m[5] = 1 - 2 * (qx * qx + qz * qz);
  m[6] = 2 * (qy * qz + qx * qw);
  m[8] = 2 * (qx * qz + qy * qw);
  m[9] = 2 * (qy * qz - qx * qw);
  m[10] = 1 - 2 * (qx * qx + qy * qy);
  m[12] = t[0];
  m[13] = t[1];
  m[14] = t[2];
  return m;
}

export function perspective(fovyRad, aspect, near, far) {
  const f = 1 / Math.tan(fovyRad / 2);
  const m = new Float64Array(16);
  m[0] = f / aspect;
  m[5] = f;
  m[10] = (far + near) / (near - far);
  m[11] = -1;
  m[14] = (2 * far * near) / (near - far);
  return m;
}

/** View matrix (world -> GL eye space, looking down -z). */
export function lookAt(eye, target, up) {
  const zAxis = vec3.normalize(vec3.sub(eye, target));
  let xAxis = vec3.cross(up, zAxis);
  if (vec3.length(xAxis) < 1e-9) xAxis = vec3.cross([0, 0, 1], zAxis);
  xAxis = vec3.normalize(xAxis);
  const yAxis = vec3.cross(zAxis, xAxis);
  const m = identity();
  m[0] = xAxis[0]; m[4] = xAxis[1]; m[8] = xAxis[2];
  m[1] = yAxis[0]; m[5] = yAxis[1]; m[9] = yAxis[2];
  m[2] = zAxis[0]; m[6] = zAxis[1]; m[10] = zAxis[2];
  m[12] = -vec3.dot(xAxis, eye);
  m[13] = -vec3.dot(yAxis, eye);
  m[14] = -vec3.dot(zAxis, eye);
  return m;
}
