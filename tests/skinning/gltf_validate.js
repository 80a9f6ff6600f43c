// Runs the Khronos glTF validator (npm package gltf-validator) on .glb files.
//   NODE_PATH=/path/to/node_modules node gltf_validate.js file.glb [...]
// Prints one line per file: errors, warnings, infos, hints and the first messages; exits 1 when
// any file has an error, 2 when the validator package cannot be loaded.
const fs = require('fs');
let validator;
try {
  validator = require('gltf-validator');
} catch (e) {
  console.log('gltf-validator not found (npm install gltf-validator; set NODE_PATH)');
  process.exit(2);
}
(async () => {
  let failed = false;
  for (const file of process.argv.slice(2)) {
    const report = await validator.validateBytes(new Uint8Array(fs.readFileSync(file)));
    const i = report.issues;
    console.log(`${file}: errors ${i.numErrors} warnings ${i.numWarnings} infos ${i.numInfos} hints ${i.numHints}`);
    for (const m of i.messages.slice(0, 12))
      console.log(`  [${m.severity}] ${m.code} ${m.pointer || ''}: ${m.message}`);
    if (i.numErrors > 0) failed = true;
  }
  process.exit(failed ? 1 : 0);
})();
