// Runs the Khronos glTF-Validator (npm package gltf-validator) on each file
// given, prints one summary line per file, and exits 1 when any has an error.
//   node tests/gltf/validate.js MODULES_DIR FILE...
const fs = require("fs");
const path = require("path");
const validator = require(path.join(path.resolve(process.argv[2]), "gltf-validator"));

async function main() {
  let failed = false;
  for (const file of process.argv.slice(3)) {
    const report = await validator.validateBytes(new Uint8Array(fs.readFileSync(file)), {
      uri: path.basename(file),
      maxIssues: 1000,
    });
    const i = report.issues;
    console.log(`${file}: ${i.numErrors} errors, ${i.numWarnings} warnings, ${i.numInfos} infos, ${i.numHints} hints`);
    for (const m of i.messages.filter((m) => m.severity <= 1).slice(0, 20))
      console.log(`  ${m.severity === 0 ? "error" : "warning"} ${m.code} ${m.pointer || ""}: ${m.message}`);
    if (i.numErrors > 0) failed = true;
  }
  process.exit(failed ? 1 : 0);
}
main().catch((e) => {
  console.error("validate.js: " + e);
  process.exit(2);
});
