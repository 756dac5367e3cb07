// Validate a glTF 2.0 file with the Khronos glTF validator (npm package gltf-validator) and print its JSON report.
// Usage: NODE_PATH=<folder holding node_modules/gltf-validator> node validate_gltf.js FILE.glb
const fs = require("fs");
const validator = require("gltf-validator");

const bytes = new Uint8Array(fs.readFileSync(process.argv[2]));
validator.validateBytes(bytes).then((report) => {
  console.log(JSON.stringify(report, null, 1));
  process.exit(report.issues.numErrors === 0 ? 0 : 1);
}).catch((error) => {
  console.error(String(error));
  process.exit(2);
});
