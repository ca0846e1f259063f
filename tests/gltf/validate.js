// SPDX-License-Identifier: MIT OR Apache-2.0
// Runs the Khronos glTF-Validator (npm package `gltf-validator`, installed here by .ci/run) on a
// .glb or a .gltf (its .bin and images read from beside it) and prints its issue summary as JSON;
// exit 1 when it reports errors.
const validator = require('gltf-validator');
const fs = require('fs');
const path = require('path');
const file = process.argv[2];
const bytes = new Uint8Array(fs.readFileSync(file));
validator
  .validateBytes(bytes, {
    uri: path.basename(file),
    externalResourceFunction: (uri) =>
      new Promise((resolve, reject) => {
        fs.readFile(path.join(path.dirname(file), decodeURIComponent(uri)), (err, data) =>
          err ? reject(err.toString()) : resolve(new Uint8Array(data)));
      }),
  })
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
