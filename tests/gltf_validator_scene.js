// Writes the scene CliGltfValidator refines (tests/cli_gltf_validator.sh): a 2 × 2 floor of
// two triangles with TEXCOORD_0, COLOR_0 (VEC4) and TANGENT but no NORMAL, under a 1 × 1 lid
// of two triangles without NORMAL that shadows part of it (the scene of test_cli_refine.cpp,
// floor without normals). The bake splits the flat-normal vertices and refines the floor along
// the lid's shadow, so the baked file holds every attribute kind interpolated.
//
//   node gltf_validator_scene.js OUT.gltf
'use strict';
const fs = require('fs');

const chunks = [], views = [], accessors = [];
let offset = 0;
function accessor(values, type, componentType = 5126) {
  const width = {SCALAR: 1, VEC2: 2, VEC3: 3, VEC4: 4}[type];
  const bytes = Buffer.from((componentType === 5125 ? new Uint32Array(values) : new Float32Array(values)).buffer);
  views.push({buffer: 0, byteOffset: offset, byteLength: bytes.length});
  const a = {bufferView: views.length - 1, componentType, count: values.length / width, type};
  if (type === 'VEC3' && componentType === 5126) {  // POSITION needs its bounds
    a.min = [0, 1, 2].map((c) => Math.min(...values.filter((_, i) => i % 3 === c)));
    a.max = [0, 1, 2].map((c) => Math.max(...values.filter((_, i) => i % 3 === c)));
  }
  accessors.push(a);
  chunks.push(bytes);
  offset += bytes.length;
  return accessors.length - 1;
}

// Corners (x, z) of a square of side `size` centred on (cx, cz) at height y.
function square(cx, y, cz, size) {
  const h = size / 2;
  return [cx - h, y, cz - h, cx + h, y, cz - h, cx - h, y, cz + h, cx + h, y, cz + h];
}
const floor = square(0, 0, 0, 2);
const uv = [], color = [], tangent = [];
for (let v = 0; v < 4; ++v) {
  const x = floor[3 * v], z = floor[3 * v + 2];
  uv.push((x + 1) / 2, (z + 1) / 2);
  color.push((x + 1) / 2, (z + 1) / 2, 0.5, 1);
  tangent.push(1, 0, 0, -1);
}
const floorPrimitive = {
  attributes: {POSITION: accessor(floor, 'VEC3'), TEXCOORD_0: accessor(uv, 'VEC2'), COLOR_0: accessor(color, 'VEC4'),
               TANGENT: accessor(tangent, 'VEC4')},
  indices: accessor([0, 3, 1, 0, 2, 3], 'SCALAR', 5125),  // facing +Y
};
const lidPrimitive = {
  attributes: {POSITION: accessor(square(0.25, 0.3, 0, 1), 'VEC3')},
  indices: accessor([0, 1, 3, 0, 3, 2], 'SCALAR', 5125),  // facing -Y, towards the floor
};
const data = Buffer.concat(chunks);
const doc = {
  asset: {version: '2.0'},
  scene: 0,
  scenes: [{nodes: [0, 1]}],
  nodes: [{name: 'Floor', mesh: 0}, {name: 'Lid', mesh: 1}],
  meshes: [{primitives: [floorPrimitive]}, {primitives: [lidPrimitive]}],
  accessors,
  bufferViews: views,
  buffers: [{byteLength: data.length, uri: 'data:application/octet-stream;base64,' + data.toString('base64')}],
};
fs.writeFileSync(process.argv[2], JSON.stringify(doc));
