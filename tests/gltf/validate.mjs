// Validates glTF/GLB files with the Khronos glTF validator; prints one JSON report per file
// (a list, in the order given): errors, warnings, infos and the first messages.
// Usage: node validate.mjs FILE.glb [FILE.glb ...]
import { readFileSync } from 'node:fs';
import validator from 'gltf-validator';

const reports = [];
for (const path of process.argv.slice(2)) {
  const report = await validator.validateBytes(new Uint8Array(readFileSync(path)),
                                               { maxIssues: 500 });
  const issues = report.issues;
  reports.push({
    file: path,
    errors: issues.numErrors,
    warnings: issues.numWarnings,
    infos: issues.numInfos,
    // severity: 0 error, 1 warning, 2 info, 3 hint
    messages: issues.messages.filter((m) => m.severity <= 1).slice(0, 20)
      .map((m) => `${m.code} ${m.pointer || ''}: ${m.message}`),
  });
}
console.log(JSON.stringify(reports));
