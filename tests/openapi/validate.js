// Validates an OpenAPI document with @apidevtools/swagger-parser, the standard validator of the
// npm ecosystem. For OpenAPI 3.x it checks the document against the OpenAPI 3.0/3.1 meta-schema
// and that every $ref resolves; the semantic checks it makes for Swagger 2.0 it does not make for
// 3.x ("We don't (yet) support validating against the OpenAPI spec", lib/validators/spec.js), so
// two of them are made here, on the dereferenced document: each {parameter} of a path is declared
// `in: path` and required, and operationIds are unique.
// Prints each error and exits 1, or prints "valid" with the document's version.
// Usage: node validate.js openapi.json   (the package is found through NODE_PATH: the build's
// npm ci of tests/openapi/package-lock.json)
"use strict";
const SwaggerParser = require("@apidevtools/swagger-parser");

const kMethods = ["get", "put", "post", "delete", "options", "head", "patch", "trace"];

// The errors of the two checks swagger-parser leaves out for OpenAPI 3.x.
function SemanticErrors(api) {
  const errors = [];
  const operationIds = new Map();
  for (const [path, item] of Object.entries(api.paths || {})) {
    const templated = [...path.matchAll(/\{([^}]+)\}/g)].map((m) => m[1]);
    for (const method of kMethods) {
      const op = item[method];
      if (!op) continue;
      const where = `${method.toUpperCase()} ${path}`;
      const declared = [...(item.parameters || []), ...(op.parameters || [])].filter((p) => p.in === "path");
      for (const name of templated) {
        const p = declared.find((d) => d.name === name);
        if (!p) errors.push(`${where}: path parameter {${name}} is not declared (in: path)`);
        else if (p.required !== true) errors.push(`${where}: path parameter {${name}} must be required: true`);
      }
      for (const p of declared) {
        if (!templated.includes(p.name)) errors.push(`${where}: parameter ${p.name} (in: path) is not in the path`);
      }
      if (op.operationId) {
        if (operationIds.has(op.operationId)) {
          errors.push(`${where}: operationId ${op.operationId} is also ${operationIds.get(op.operationId)}'s`);
        }
        operationIds.set(op.operationId, where);
      }
    }
  }
  return errors;
}

async function Main(file) {
  let api;
  try {
    api = await SwaggerParser.validate(file);
  } catch (err) {
    console.error(`${file}: not a valid OpenAPI document:`);
    console.error(err.message);
    return 1;
  }
  const errors = SemanticErrors(api);
  if (errors.length > 0) {
    console.error(`${file}: valid against the OpenAPI ${api.openapi} schema, but:`);
    for (const e of errors) console.error(`  ${e}`);
    return 1;
  }
  console.log(`${file}: valid OpenAPI ${api.openapi} (${Object.keys(api.paths || {}).length} paths)`);
  return 0;
}

const file = process.argv[2];
if (!file) {
  console.error("usage: node validate.js OPENAPI.json");
  process.exit(2);
}
Main(file).then((code) => process.exit(code));
