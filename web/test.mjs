// Opens the built page in headless Chromium (Debian's, driven by playwright-core),
// runs its scripted test (`?frames=N`), and writes OUT_DIR/web.png (the app's own
// frame readback) and OUT_DIR/web.json (adapter, frames, query results, checks).
// Exits 1 when the page logs an error, has no WebGPU adapter, renders a blank
// frame, or its trail does not differ from untouched snow.
//   node web/test.mjs URL OUT_DIR [FRAMES]
import { chromium } from "playwright-core";
import { mkdir, writeFile } from "node:fs/promises";
import { join } from "node:path";

const [url, outDir, framesArg] = process.argv.slice(2);
const frames = Number(framesArg ?? 60);
const browserPath = process.env.CHROMIUM ?? "/usr/bin/chromium";
await mkdir(outDir, { recursive: true });

const problems = [];
const consoleLines = [];
const browser = await chromium.launch({
  executablePath: browserPath,
  headless: true,
  args: [
    "--headless=new", "--no-sandbox", "--enable-unsafe-webgpu",
    // SwiftShader's Vulkan for WebGPU (no GPU here); ANGLE on SwiftShader for the canvas.
    "--enable-features=Vulkan", "--use-vulkan=swiftshader", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
  ],
});
let report = null;
let checks = {};
try {
  const [vw, vh] = (process.env.SNOWPACK_WEB_VIEWPORT ?? "1100x640").split("x").map(Number);
  const page = await browser.newPage({ viewport: { width: vw, height: vh } });
  page.on("console", (m) => {
    consoleLines.push(`${m.type()}: ${m.text()}`);
    if (m.type() === "error") problems.push(`console error: ${m.text()}`);
  });
  page.on("pageerror", (e) => problems.push(`page error: ${e.message}`));
  // A lighter window than the default scene's: SwiftShader runs WebGPU on the CPU.
  const extra = process.env.SNOWPACK_WEB_QUERY ?? "resolution=128&spheres=4&shadow=512&quads=4";
  await page.goto(`${url}?frames=${frames}${extra ? "&" + extra : ""}`);
  const limitS = Number(process.env.SNOWPACK_WEB_TIMEOUT_S ?? 420);
  const started = Date.now();
  const progress = setInterval(async () => {
    const [n, timings] = await page.evaluate(() => [window.snowpackFrame ?? 0, window.snowpackTimings ?? ""]).catch(() => ["?", ""]);
    console.log(`web test: frame ${n} of ${frames} after ${((Date.now() - started) / 1000).toFixed(0)} s`);
    if (process.env.SNOWPACK_WEB_TIMINGS) console.log(`  GPU ms: ${timings}`);
  }, 20000);
  const done = await page
    .waitForFunction(() => window.snowpackReport || window.snowpackError, null, { timeout: limitS * 1000, polling: 500 })
    .then(() => true, () => false);
  clearInterval(progress);
  if (!done) problems.push(`no report within ${limitS} s`);
  const result = await page.evaluate(() => ({
    report: window.snowpackReport ?? null,
    error: window.snowpackError ?? null,
    png: window.snowpackPng ? Array.from(window.snowpackPng) : null,
    gpu: !!navigator.gpu,
  }));
  if (result.error) problems.push(`page: ${result.error}`);
  if (!result.gpu) problems.push("navigator.gpu is missing");
  if (result.png) await writeFile(join(outDir, "web.png"), Buffer.from(result.png));
  else problems.push("the page gave no frame");
  if (result.report) {
    report = JSON.parse(result.report);
    // Checked again here on the pixels the page read back (decoded in the page's own canvas).
    checks = await page.evaluate(async (r) => {
      const blob = new Blob([window.snowpackPng], { type: "image/png" });
      const bitmap = await createImageBitmap(blob);
      const canvas = new OffscreenCanvas(bitmap.width, bitmap.height);
      const g = canvas.getContext("2d");
      g.drawImage(bitmap, 0, 0);
      const data = g.getImageData(0, 0, bitmap.width, bitmap.height).data;
      const luma = (k) => 0.2126 * data[k] + 0.7152 * data[k + 1] + 0.0722 * data[k + 2];
      let sum = 0, sq = 0;
      for (let k = 0; k < data.length; k += 4) { const l = luma(k); sum += l; sq += l * l; }
      const n = data.length / 4, mean = sum / n;
      const patch = (p) => {
        if (!p) return null;
        const [cx, cy] = [Math.floor(p[0]), Math.floor(p[1])];
        let s = 0, c = 0;
        for (let y = cy - 3; y <= cy + 3; y++) for (let x = cx - 3; x <= cx + 3; x++) {
          if (x < 0 || y < 0 || x >= bitmap.width || y >= bitmap.height) return null;
          s += luma((y * bitmap.width + x) * 4); c++;
        }
        return s / c;
      };
      return { width: bitmap.width, height: bitmap.height, luma_mean: mean, luma_spread: Math.sqrt(Math.max(0, sq / n - mean * mean)),
               trail_luma: patch(r.trail.pixel), untouched_luma: patch(r.untouched.pixel) };
    }, report);
    if (!report.adapter || !report.adapter.backend) problems.push("the report names no adapter");
    if (report.frames < frames) problems.push(`only ${report.frames} of ${frames} frames ran`);
    if (!(checks.luma_spread > 2)) problems.push(`the frame is blank (luma spread ${checks.luma_spread})`);
    if (checks.trail_luma == null || checks.untouched_luma == null) problems.push("the trail or the untouched snow is off the frame");
    else if (Math.abs(checks.trail_luma - checks.untouched_luma) < 4)
      problems.push(`the trail (luma ${checks.trail_luma.toFixed(1)}) looks like untouched snow (${checks.untouched_luma.toFixed(1)})`);
    if (!(report.trail.pressed_m > 0.05)) problems.push(`the trail probe is pressed only ${report.trail.pressed_m} m`);
    if (!(Math.abs(report.untouched.pressed_m) < 0.01)) problems.push(`the untouched probe is pressed ${report.untouched.pressed_m} m`);
  } else if (!result.error) {
    problems.push("the page gave no report");
  }
} finally {
  await browser.close();
}
await writeFile(join(outDir, "web.json"), JSON.stringify({ ...report, checks, problems, console: consoleLines }, null, 2) + "\n");
for (const p of problems) console.error(`web test: ${p}`);
if (report) {
  console.log(`web test: ${report.frames} frames on ${report.adapter.name} (${report.adapter.backend}); trail pressed ${report.trail.pressed_m.toFixed(3)} m, ` +
    `luma trail ${checks.trail_luma?.toFixed(1)} vs untouched ${checks.untouched_luma?.toFixed(1)}, spread ${checks.luma_spread?.toFixed(1)}`);
}
process.exit(problems.length ? 1 : 0);
