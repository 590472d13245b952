// Bundles the page of `fiberfem web` into one folder (docs/web.md): index.html, app.js
// (three.js and the page's modules, minified by esbuild), style.css. Run at build time by
// CMake (clients/web/CMakeLists.txt) or `npm run build`; the page needs no network after.
//   node build.mjs OUTDIR
import { copyFileSync, existsSync, mkdirSync } from "node:fs";
import { dirname, join } from "node:path";
import { fileURLToPath } from "node:url";

const here = dirname(fileURLToPath(import.meta.url));
const out = process.argv[2];
if (!out) {
  console.error("usage: node build.mjs OUTDIR");
  process.exit(2);
}
if (!existsSync(join(here, "node_modules", "esbuild")) || !existsSync(join(here, "node_modules", "three"))) {
  console.error(`${join(here, "node_modules")} lacks esbuild or three: run scripts/setup.sh (npm ci in clients/web)`);
  process.exit(3);
}
const esbuild = await import("esbuild");
mkdirSync(out, { recursive: true });
await esbuild.build({
  entryPoints: [join(here, "src", "main.js")],
  bundle: true,
  minify: true,
  format: "esm",
  target: "es2020",
  outfile: join(out, "app.js"),
  logLevel: "warning",
});
for (const f of ["index.html", "style.css"]) copyFileSync(join(here, "src", f), join(out, f));
