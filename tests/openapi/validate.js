// Validates an OpenAPI document with @apidevtools/swagger-parser (the standard validator of the
// npm ecosystem: the OpenAPI 3.0/3.1 meta-schema, then its own semantic checks: $refs resolve,
// path parameters are declared, operationIds are unique). Prints each error and exits 1, or prints
// "valid" with the document's version. Usage: node validate.js openapi.json
// The package is found through NODE_PATH (the build's npm ci of tests/openapi/package-lock.json).
"use strict";
const SwaggerParser = require("@apidevtools/swagger-parser");

const file = process.argv[2];
if (!file) {
  console.error("usage: node validate.js OPENAPI.json");
  process.exit(2);
}
SwaggerParser.validate(file).then(
  (api) => {
    const paths = Object.keys(api.paths || {}).length;
    console.log(`${file}: valid OpenAPI ${api.openapi} (${paths} paths)`);
  },
  (err) => {
    console.error(`${file}: not a valid OpenAPI document:`);
    console.error(err.message);
    process.exit(1);
  });
