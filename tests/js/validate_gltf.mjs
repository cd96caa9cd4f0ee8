// Validate GLB files with the Khronos glTF validator (npm gltf-validator); prints one JSON line per file:
// {"file", "errors", "warnings", "messages": [the first errors]}.
import fs from "node:fs";
import path from "node:path";
import validator from "gltf-validator";

for (const file of process.argv.slice(2)) {
  const bytes = new Uint8Array(fs.readFileSync(file));
  const report = await validator.validateBytes(bytes, {
    uri: path.basename(file), maxIssues: 200,
    externalResourceFunction: () => Promise.reject(new Error("no external resources")),
  });
  const errors = report.issues.messages.filter((m) => m.severity === 0);
  console.log(JSON.stringify({ file, errors: report.issues.numErrors, warnings: report.issues.numWarnings,
    infos: report.issues.numInfos, messages: errors.slice(0, 5).map((m) => `${m.code}: ${m.message} (${m.pointer || ""})`),
    warningCodes: [...new Set(report.issues.messages.filter((m) => m.severity === 1).map((m) => m.code))] }));
}
