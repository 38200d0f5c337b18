// Looks at a bake in a real glTF viewer: loads OUTDIR/baked.gltf (or
// baked.glb) with three.js's GLTFLoader in headless Chromium (software
// WebGL), renders it from the view in OUTDIR/report.json, writes the
// picture to OUTDIR/viewer.png and compares it with OUTDIR/render.png
// (nusselt's own render of the same view and exposure). With a lightmap
// (a .gltf whose materials have an emissive texture), it looks a second
// time with KHR_materials_unlit taken out, as an engine that shades with
// its own lights would see it: the atlas through TEXCOORD_1 then makes the
// picture (viewer-lightmap.png), and it is held to the same bounds.
//
// Usage: node tools/view_bake.mjs OUTDIR [CHROMIUM]
// Setup: npm install --prefix tools; Debian's chromium (default
//        /usr/bin/chromium).
//
// Fails (exit 1) when the page cannot load the bake, when the picture is
// nearly all black or all white, or when its mean absolute difference from
// render.png exceeds MAX_MEAN_DIFFERENCE (8-bit levels) or its mean level
// differs by more than MAX_MEAN_SHIFT.

import { readFile, writeFile } from "node:fs/promises";
import { createRequire } from "node:module";
import path from "node:path";

const require = createRequire(import.meta.url);
const MAX_MEAN_DIFFERENCE = 12;
const MAX_MEAN_SHIFT = 6;

function fail(message, code = 1) {
  console.error(`error: ${message}`);
  process.exit(code);
}

if (process.argv.length < 3 || process.argv.length > 4) {
  fail("usage: node tools/view_bake.mjs OUTDIR [CHROMIUM]", 2);
}
const outdir = path.resolve(process.argv[2]);
const chromium = process.argv[3] ?? "/usr/bin/chromium";
const here = path.dirname(new URL(import.meta.url).pathname);

let playwright;
try {
  playwright = require("playwright-core");
} catch {
  fail("playwright-core is not installed: run `npm install --prefix tools`");
}

const report = JSON.parse(await readFile(path.join(outdir, "report.json"), "utf8"));
const view = report.view;
const bake = await readFile(path.join(outdir, "baked.glb")).then(
  () => "baked.glb",
  () => "baked.gltf",
);

// The same document with KHR_materials_unlit taken out, when it has a
// lightmap (an emissive texture) to show instead.
let withoutUnlit = null;
if (bake === "baked.gltf") {
  const json = JSON.parse(await readFile(path.join(outdir, bake), "utf8"));
  if ((json.materials ?? []).some((m) => m.emissiveTexture)) {
    for (const m of json.materials) delete m.extensions?.KHR_materials_unlit;
    json.extensionsUsed = (json.extensionsUsed ?? []).filter((e) => e !== "KHR_materials_unlit");
    withoutUnlit = json;
  }
}

const page_html = `<!doctype html><html><body style="margin:0">
<script type="importmap">{"imports": {"three": "/three/build/three.module.js",
  "three/addons/": "/three/examples/jsm/"}}</script>
<script type="module">
import * as THREE from "three";
import { GLTFLoader } from "three/addons/loaders/GLTFLoader.js";
const view = ${JSON.stringify(view)};
const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(1);
renderer.setSize(view.width, view.height);
renderer.outputColorSpace = THREE.SRGBColorSpace;
document.body.appendChild(renderer.domElement);
const camera = new THREE.PerspectiveCamera(view.yfov * 180 / Math.PI, view.width / view.height, 1e-3, 1e4);
const eye = new THREE.Vector3(...view.eye);
camera.position.copy(eye);
camera.up.set(...view.up);
camera.lookAt(eye.clone().add(new THREE.Vector3(...view.forward)));
window.look = (url) => new Promise((resolve, reject) => {
  new GLTFLoader().load(url, (gltf) => {
    const scene = new THREE.Scene();
    scene.background = new THREE.Color(0, 0, 0);
    scene.add(gltf.scene);
    renderer.render(scene, camera);
    resolve(renderer.domElement.toDataURL("image/png"));
  }, undefined, (e) => reject(new Error(String(e && e.message || e))));
});
window.ready = true;
</script></body></html>`;

// Runs in the page: both pictures decoded to RGBA bytes and compared.
async function compare([a, b]) {
  async function pixels(src) {
    const image = new Image();
    image.src = src;
    await image.decode();
    const canvas = new OffscreenCanvas(image.width, image.height);
    const context = canvas.getContext("2d");
    context.drawImage(image, 0, 0);
    return context.getImageData(0, 0, image.width, image.height);
  }
  const [x, y] = [await pixels(a), await pixels("data:image/png;base64," + b)];
  if (x.width !== y.width || x.height !== y.height) return { size: [x.width, x.height, y.width, y.height] };
  let diff = 0, mx = 0, my = 0, dark = 0, bright = 0;
  const n = x.width * x.height;
  for (let i = 0; i < n; i++) {
    for (let c = 0; c < 3; c++) {
      const p = x.data[4 * i + c], q = y.data[4 * i + c];
      diff += Math.abs(p - q); mx += p; my += q;
    }
    const level = (x.data[4 * i] + x.data[4 * i + 1] + x.data[4 * i + 2]) / 3;
    if (level < 3) dark++;
    if (level > 252) bright++;
  }
  return { diff: diff / (3 * n), viewer: mx / (3 * n), own: my / (3 * n), dark: dark / n, bright: bright / n };
}

const browser = await playwright.chromium.launch({
  executablePath: chromium,
  args: [
    "--headless", "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader", "--disable-quic", "--no-first-run",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
  ],
});
try {
  const page = await browser.newPage();
  await page.route("http://bake.invalid/**", async (route) => {
    const url = new URL(route.request().url());
    const types = { ".js": "text/javascript", ".gltf": "model/gltf+json", ".html": "text/html" };
    let file;
    if (url.pathname === "/") {
      return route.fulfill({ body: page_html, contentType: "text/html" });
    } else if (url.pathname === "/lit/baked.gltf") {
      return route.fulfill({ body: JSON.stringify(withoutUnlit), contentType: types[".gltf"] });
    } else if (url.pathname.startsWith("/lit/")) {
      file = path.join(outdir, decodeURIComponent(url.pathname.slice(5)));
    } else if (url.pathname.startsWith("/three/")) {
      file = path.join(here, "node_modules", url.pathname);
    } else if (url.pathname.startsWith("/out/")) {
      file = path.join(outdir, decodeURIComponent(url.pathname.slice(5)));
    } else {
      return route.fulfill({ status: 404 });
    }
    try {
      const body = await readFile(file);
      return route.fulfill({ body, contentType: types[path.extname(file)] ?? "application/octet-stream" });
    } catch {
      return route.fulfill({ status: 404 });
    }
  });
  await page.goto("http://bake.invalid/");
  await page.waitForFunction(() => window.ready, null, { timeout: 60000 });
  const own = (await readFile(path.join(outdir, "render.png"))).toString("base64");
  const three = JSON.parse(await readFile(path.join(here, "node_modules/three/package.json"), "utf8"));
  const looks = [["as it is (unlit, COLOR_0)", `/out/${bake}`, "viewer.png"]];
  if (withoutUnlit) looks.push(["lit by its lightmap (emissive, TEXCOORD_1)", "/lit/baked.gltf", "viewer-lightmap.png"]);
  for (const [what, url, name] of looks) {
    let picture;
    try {
      picture = await page.evaluate((u) => window.look(u), url);
    } catch (e) {
      fail(`three.js could not load the bake: ${e.message}`);
    }
    await writeFile(path.join(outdir, name), Buffer.from(picture.split(",")[1], "base64"));
    const stats = await page.evaluate(compare, [picture, own]);
    if (stats.size) fail(`${name} and render.png differ in size: ${stats.size}`);
    console.log(
      `three.js ${three.version}, the bake ${what}: mean level ${stats.viewer.toFixed(1)} ` +
        `(render.png ${stats.own.toFixed(1)}), mean |difference| ${stats.diff.toFixed(2)} levels, ` +
        `${(100 * stats.dark).toFixed(1)} % black, ${(100 * stats.bright).toFixed(1)} % white`,
    );
    if (stats.dark > 0.95 || stats.bright > 0.95) fail(`${name}: the viewer shows the bake all black or all white`);
    if (Math.abs(stats.viewer - stats.own) > MAX_MEAN_SHIFT) fail(`${name} is brighter or darker than render.png`);
    if (stats.diff > MAX_MEAN_DIFFERENCE) fail(`${name} differs from render.png`);
  }
} finally {
  await browser.close();
}
