// The map's triangle mesh (slam.exportMesh) drawn in place of the splats:
// parseGlb (used by the worker, no DOM) reads the arrays back out of the .glb
// the module wrote, MeshView draws them with the renderer's camera.

const GLB_MAGIC = 0x46546c67; // 'glTF'
const CHUNK_JSON = 0x4e4f534a;
const CHUNK_BIN = 0x004e4942;

/**
 * The first triangle primitive of a .glb as typed arrays (copies):
 * {positions: Float32Array (3 per vertex, the buffer's frame: the map's world
 * frame, metres; the file's node turns it for glTF's +y up, ignored here),
 * normals: Float32Array, colours: Uint8Array (RGBA8), indices: Uint32Array}.
 * Throws on a file that is not such a .glb.
 */
export function parseGlb(bytes) {
  const data = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  if (bytes.byteLength < 20 || data.getUint32(0, true) !== GLB_MAGIC) throw new Error('not a .glb file');
  let json = null;
  let bin = null;
  for (let at = 12; at + 8 <= bytes.byteLength; ) {
    const length = data.getUint32(at, true);
    const type = data.getUint32(at + 4, true);
    const body = bytes.subarray(at + 8, at + 8 + length);
    if (type === CHUNK_JSON) json = JSON.parse(new TextDecoder().decode(body));
    else if (type === CHUNK_BIN) bin = body;
    at += 8 + length;
  }
  if (!json) throw new Error('.glb without a JSON chunk');
  const empty = { positions: new Float32Array(0), normals: new Float32Array(0), colours: new Uint8Array(0), indices: new Uint32Array(0) };
  const primitive = json.meshes?.[0]?.primitives?.[0];
  if (!primitive || !bin) return empty;
  const Arrays = { 5121: Uint8Array, 5125: Uint32Array, 5126: Float32Array };
  const Sizes = { SCALAR: 1, VEC3: 3, VEC4: 4 };
  const read = (index) => {
    const accessor = json.accessors[index];
    const view = json.bufferViews[accessor.bufferView];
    const Type = Arrays[accessor.componentType];
    const n = accessor.count * Sizes[accessor.type];
    if (!Type || !n) return new (Type || Float32Array)(0);
    const offset = (view.byteOffset || 0) + (accessor.byteOffset || 0);
    // A copy: the slice is aligned for the typed array, and transferable.
    return new Type(bin.slice(offset, offset + n * Type.BYTES_PER_ELEMENT).buffer);
  };
  const a = primitive.attributes;
  return {
    positions: read(a.POSITION),
    normals: read(a.NORMAL),
    colours: read(a.COLOR_0),
    indices: primitive.indices === undefined ? new Uint32Array(0) : read(primitive.indices),
  };
}

const MESH_VS = `#version 300 es
layout(location = 0) in vec3 aPosition;
layout(location = 1) in vec3 aNormal;
layout(location = 2) in vec4 aColour;
uniform mat4 uView;
uniform mat4 uProj;
out vec3 vColour;
void main() {
  vec4 eye = uView * vec4(aPosition, 1.0);
  gl_Position = uProj * eye;
  // Headlight, two-sided: the mesh's normals may face either way after the
  // display's mirror (ICL-NUIM) and the view shows both sides of walls.
  vec3 n = normalize(mat3(uView) * aNormal);
  float light = 0.35 + 0.65 * abs(dot(n, normalize(-eye.xyz)));
  vColour = aColour.rgb * light;
}`;

const MESH_FS = `#version 300 es
precision mediump float;
in vec3 vColour;
out vec4 outColour;
void main() { outColour = vec4(vColour, 1.0); }`;

function compile(gl) {
  const program = gl.createProgram();
  for (const [type, source] of [
    [gl.VERTEX_SHADER, MESH_VS],
    [gl.FRAGMENT_SHADER, MESH_FS],
  ]) {
    const shader = gl.createShader(type);
    gl.shaderSource(shader, source);
    gl.compileShader(shader);
    if (!gl.getShaderParameter(shader, gl.COMPILE_STATUS)) throw new Error(`mesh shader: ${gl.getShaderInfoLog(shader)}`);
    gl.attachShader(program, shader);
  }
  gl.linkProgram(program);
  if (!gl.getProgramParameter(program, gl.LINK_STATUS)) throw new Error(`mesh program: ${gl.getProgramInfoLog(program)}`);
  return { program, uView: gl.getUniformLocation(program, 'uView'), uProj: gl.getUniformLocation(program, 'uProj') };
}

/** One triangle mesh on the GPU, replaced as a whole by set(). */
export class MeshView {
  constructor(gl) {
    this.gl = gl;
    this.shader = compile(gl);
    this.vao = gl.createVertexArray();
    this.buffers = [gl.createBuffer(), gl.createBuffer(), gl.createBuffer(), gl.createBuffer()];
    this.indexCount = 0;
  }

  /** mesh: parseGlb's arrays, in the display frame. */
  set(mesh) {
    const gl = this.gl;
    gl.bindVertexArray(this.vao);
    const attributes = [
      [mesh.positions, 3, gl.FLOAT, false],
      [mesh.normals, 3, gl.FLOAT, false],
      [mesh.colours, 4, gl.UNSIGNED_BYTE, true],
    ];
    attributes.forEach(([array, size, type, normalised], i) => {
      gl.bindBuffer(gl.ARRAY_BUFFER, this.buffers[i]);
      gl.bufferData(gl.ARRAY_BUFFER, array, gl.STATIC_DRAW);
      gl.enableVertexAttribArray(i);
      gl.vertexAttribPointer(i, size, type, normalised, 0, 0);
    });
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, this.buffers[3]);
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, mesh.indices, gl.STATIC_DRAW);
    gl.bindVertexArray(null);
    this.indexCount = mesh.indices.length;
  }

  clear() {
    this.indexCount = 0;
  }

  /** view, proj: the renderer's Float32Array matrices (column-major). */
  draw(view, proj) {
    if (this.indexCount === 0) return;
    const gl = this.gl;
    gl.useProgram(this.shader.program);
    gl.uniformMatrix4fv(this.shader.uView, false, view);
    gl.uniformMatrix4fv(this.shader.uProj, false, proj);
    gl.bindVertexArray(this.vao);
    gl.drawElements(gl.TRIANGLES, this.indexCount, gl.UNSIGNED_INT, 0);
    gl.bindVertexArray(null);
  }
}
