// SPDX-License-Identifier: MIT OR Apache-2.0
// Runs the Khronos glTF-Validator (npm package `gltf-validator`, installed here by .ci/run) on a
// .glb and prints its issue summary as JSON; exit 1 when it reports errors.
const validator = require('gltf-validator');
const fs = require('fs');
const bytes = new Uint8Array(fs.readFileSync(process.argv[2]));
validator
  .validateBytes(bytes)
  .then((report) => {
    const i = report.issues;
    console.log(JSON.stringify({
      errors: i.numErrors,
      warnings: i.numWarnings,
      messages: i.messages.filter((m) => m.severity <= 1).slice(0, 10),
    }));
    process.exit(i.numErrors > 0 ? 1 : 0);
  })
  .catch((e) => {
    console.error(e);
    process.exit(2);
  });
