// Drives the helper joints of a skin that `curvenet bake --helpers` wrote,
// for clips that do not key them (an engine's own animation, IK, retargeted
// capture): the reference of docs/bake.md, "Playing other clips in an engine".
// A helper is a bone whose glTF extras (three.js's userData) name its two
// joints: {"curvenet_helper": ["a", "b"]}. Its skinning matrix is the
// dual-quaternion mean of theirs (rigid parts, the short way round from the
// first), times the mean of their uniform scales; its world is that times
// its rest world. Call after the skeleton is posed and its world matrices
// updated, then update the world matrices again. THREE is the three.js
// module the scene was made with.

/** The helpers of a skinned mesh: [{bone, a, b, restWorld}] (indices into skeleton.bones). */
export function findHelpers(THREE, mesh) {
  const bones = mesh.skeleton.bones;
  const byName = new Map();
  bones.forEach((bone, i) => byName.set(bone.name, i));
  const index = (name) => {
    const i = byName.get(THREE.PropertyBinding.sanitizeNodeName(name));
    if (i === undefined) throw new Error("helper joint: no bone named " + name);
    return i;
  };
  const helpers = [];
  bones.forEach((bone, h) => {
    const pair = bone.userData && bone.userData.curvenet_helper;
    if (!pair) return;
    helpers.push({
      bone,
      a: index(pair[0]),
      b: index(pair[1]),
      restWorld: mesh.skeleton.boneInverses[h].clone().invert(),
    });
  });
  return helpers;
}

/** A joint's skinning matrix split: unit quaternion (x, y, z, w), its dual part, and its uniform scale. */
function split(THREE, m) {
  const scratch = { t: new THREE.Vector3(), s: new THREE.Vector3(), q: new THREE.Quaternion() };
  m.decompose(scratch.t, scratch.q, scratch.s);
  const q = [scratch.q.x, scratch.q.y, scratch.q.z, scratch.q.w];
  const t = [scratch.t.x, scratch.t.y, scratch.t.z];
  // dual = (0, t) q / 2
  const dual = [
    0.5 * (t[0] * q[3] + t[1] * q[2] - t[2] * q[1]),
    0.5 * (-t[0] * q[2] + t[1] * q[3] + t[2] * q[0]),
    0.5 * (t[0] * q[1] - t[1] * q[0] + t[2] * q[3]),
    0.5 * (-t[0] * q[0] - t[1] * q[1] - t[2] * q[2]),
  ];
  return { q, dual, scale: Math.cbrt(Math.abs(m.determinant())) };
}

/** Poses every helper from its two joints (their bones' world matrices must be current). */
export function driveHelpers(THREE, mesh, helpers) {
  const { bones, boneInverses } = mesh.skeleton;
  const skinning = (i) => new THREE.Matrix4().multiplyMatrices(bones[i].matrixWorld, boneInverses[i]);
  for (const h of helpers) {
    const A = split(THREE, skinning(h.a)), B = split(THREE, skinning(h.b));
    const sign = A.q[0] * B.q[0] + A.q[1] * B.q[1] + A.q[2] * B.q[2] + A.q[3] * B.q[3] < 0 ? -1 : 1;
    const r = A.q.map((x, i) => 0.5 * (x + sign * B.q[i]));
    const d = A.dual.map((x, i) => 0.5 * (x + sign * B.dual[i]));
    const n = Math.hypot(...r);
    const [x0, y0, z0, w0] = r.map((x) => x / n);
    const [x1, y1, z1, w1] = d.map((x) => x / n);
    // t = 2 (w0 v1 - w1 v0 + v0 x v1)
    const t = new THREE.Vector3(
      2 * (w0 * x1 - w1 * x0 + (y0 * z1 - z0 * y1)),
      2 * (w0 * y1 - w1 * y0 + (z0 * x1 - x0 * z1)),
      2 * (w0 * z1 - w1 * z0 + (x0 * y1 - y0 * x1)));
    const s = 0.5 * (A.scale + B.scale);
    const S = new THREE.Matrix4().compose(t, new THREE.Quaternion(x0, y0, z0, w0), new THREE.Vector3(s, s, s));
    // Its world, then its local under its parent as posed.
    const world = S.multiply(h.restWorld);
    const local = h.bone.parent ? h.bone.parent.matrixWorld.clone().invert().multiply(world) : world;
    local.decompose(h.bone.position, h.bone.quaternion, h.bone.scale);
    h.bone.updateMatrixWorld(true);
  }
}
