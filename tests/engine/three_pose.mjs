// Poses a skinned glTF binary in three.js (GLTFLoader, AnimationMixer,
// SkinnedMesh.getVertexPosition), as a game or web engine plays it, and
// writes the posed world-space positions of every skinned mesh's vertices
// (each vertex buffer once).
//   node three_pose.mjs NODE_MODULES FILE.glb TIMES_JSON OUT.bin [drive-helpers]
// TIMES_JSON: [[clip index, seconds], ...]. OUT.bin: float64, for each
// (clip, time) in order, every vertex of every skinned mesh (in the order
// the loader's scene traversal meets them), x y z. With drive-helpers, the
// clips' keys of helper joints (bake --helpers) are taken out, and the
// helpers are driven from their two joints by curvenet_helpers.mjs, as an
// engine playing clips of its own must.
import fs from "fs";
import path from "path";
import { pathToFileURL } from "url";

const [modules, file, timesJson, out, mode] = process.argv.slice(2);
const three = pathToFileURL(path.join(path.resolve(modules), "three"));
const THREE = await import(three.href + "/build/three.module.js");
const drive = mode === "drive-helpers";
const { findHelpers, driveHelpers } = drive
  ? await import(pathToFileURL(path.join(path.dirname(new URL(import.meta.url).pathname), "curvenet_helpers.mjs")).href)
  : {};
const { GLTFLoader } = await import(three.href + "/examples/jsm/loaders/GLTFLoader.js");

const bytes = fs.readFileSync(file);
const buffer = bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength);
// Node has no image decoder: textures load as none (a plugin answering every
// texture), which leaves the geometry, the skin and the clips as the loader reads them.
const loader = new GLTFLoader();
loader.register(() => ({ name: "curvenet_no_textures", loadTexture: () => Promise.resolve(null) }));
const gltf = await new Promise((resolve, reject) => loader.parse(buffer, "", resolve, reject));
const scene = gltf.scene;
// Primitives over one vertex buffer (materials of one mesh, as curvenet
// bake writes them) share the loader's position attribute: each buffer's
// vertices once, as every glTF reader (and curvenet's) takes them.
const meshes = [];
const buffers = new Set();
scene.traverse((o) => {
  if (o.isSkinnedMesh && !buffers.has(o.geometry.attributes.position)) {
    buffers.add(o.geometry.attributes.position);
    meshes.push(o);
  }
});
if (meshes.length === 0) throw new Error(file + ": no skinned mesh");
const helpers = drive ? meshes.map((m) => findHelpers(THREE, m)) : [];
if (drive) {
  const names = new Set(helpers.flat().map((h) => h.bone.name));
  if (names.size === 0) throw new Error(file + ": no helper joints to drive");
  for (const clip of gltf.animations)
    clip.tracks = clip.tracks.filter((track) => !names.has(track.name.slice(0, track.name.lastIndexOf("."))));
}
const mixer = new THREE.AnimationMixer(scene);
const times = JSON.parse(timesJson);
const count = meshes.reduce((n, m) => n + m.geometry.attributes.position.count, 0);
const result = new Float64Array(times.length * count * 3);
const v = new THREE.Vector3();
let k = 0;
for (const [clip, t] of times) {
  mixer.stopAllAction();
  const action = mixer.clipAction(gltf.animations[clip]);
  action.setLoop(THREE.LoopOnce, 1); // a repeating clip would wrap its last key to its first
  action.clampWhenFinished = true;
  action.play();
  mixer.setTime(t);
  scene.updateMatrixWorld(true);
  if (drive) meshes.forEach((m, i) => driveHelpers(THREE, m, helpers[i]));
  for (const m of meshes) {
    m.skeleton.update();
    const n = m.geometry.attributes.position.count;
    for (let i = 0; i < n; ++i) {
      m.getVertexPosition(i, v);
      v.applyMatrix4(m.matrixWorld);
      result[k++] = v.x;
      result[k++] = v.y;
      result[k++] = v.z;
    }
  }
  action.stop();
}
fs.writeFileSync(out, Buffer.from(result.buffer));
console.log(JSON.stringify({ meshes: meshes.length, vertices: count, clips: gltf.animations.map((a) => [a.name, a.duration]) }));
