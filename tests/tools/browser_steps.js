// Drive a report page in headless Chromium (Debian's, through puppeteer-core) as a person would, step by step,
// and print what each step saw as one JSON line.
//
//   node browser_steps.js CHROMIUM PAGE STEPS.json
//
// The page is opened from file:// with no network (every host resolves to nothing, requests go to a closed proxy).
// Steps: {"wait": SELECTOR, "attribute": NAME, "not": VALUE} waits until the attribute differs from VALUE;
// {"click": SELECTOR, "x": FRACTION} clicks the element at that fraction of its width (a slider's track);
// {"screenshot": PATH, "selector": SELECTOR} saves a PNG of the element; {"eval": EXPRESSION} returns its JSON value.
// Output: {"results": [...], "console": [errors and warnings the page logged], "errors": [uncaught exceptions]}.
const puppeteer = require("puppeteer-core");
const fs = require("fs");
const url = require("url");

(async () => {
  const [chromium, page, stepsFile] = process.argv.slice(2);
  const steps = JSON.parse(fs.readFileSync(stepsFile, "utf8"));
  const browser = await puppeteer.launch({
    executablePath: chromium,
    headless: true,
    args: ["--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader", "--use-angle=swiftshader",
           "--disable-background-networking", "--proxy-server=127.0.0.1:9", "--host-resolver-rules=MAP * ~NOTFOUND"],
  });
  const out = {results: [], console: [], errors: []};
  try {
    const tab = await browser.newPage();
    await tab.setViewport({width: 1200, height: 900});
    tab.on("console", (message) => {
      if (["error", "warn", "warning"].includes(message.type())) out.console.push(message.type() + ": " + message.text());
    });
    tab.on("pageerror", (error) => out.errors.push(String(error)));
    await tab.goto(url.pathToFileURL(page).href, {waitUntil: "load"});
    for (const step of steps) {
      if (step.wait) {
        await tab.waitForFunction((s, a, v) => { const e = document.querySelector(s); return e && e.getAttribute(a) !== v; },
                                  {timeout: 120000}, step.wait, step.attribute, step.not);
        out.results.push(await tab.$eval(step.wait, (e, a) => e.getAttribute(a), step.attribute));
      } else if (step.click) {
        const element = await tab.$(step.click);
        await element.scrollIntoView();
        const box = await element.boundingBox();
        await tab.mouse.click(box.x + box.width * step.x, box.y + box.height / 2);
        out.results.push(null);
      } else if (step.screenshot) {
        const element = await tab.$(step.selector);
        await element.scrollIntoView();
        await element.screenshot({path: step.screenshot});
        out.results.push(step.screenshot);
      } else if (step.eval) {
        out.results.push(await tab.evaluate(step.eval));
      }
    }
  } finally {
    await browser.close();
  }
  process.stdout.write(JSON.stringify(out) + "\n");
})().catch((error) => { process.stderr.write(String(error && error.stack || error) + "\n"); process.exit(1); });
