// Open a log in Foxglove Studio 1.48 in headless Chromium and report what a person would see.
//
//   node viewer/check.mjs URL --topics /tf,/tcp,... [--screenshot out.png] [--timeout 90000]
//
// URL is what `amex-log view` prints as "local Studio" (the log as a remote file, the layout
// preselected). Waits until every expected topic is listed in the data-source sidebar, lets the
// panels load, moves the playhead to the middle of the log, then reads the Problems tab. Prints
// one JSON object: {topics, missing, problems, pageErrors, failedRequests, urdfLoaded, seconds};
// exit code 0 if every topic is listed, there are no player problems, no page errors and no
// failed requests to the log's server, else 1.
import fs from "node:fs";
import os from "node:os";
import path from "node:path";

import { chromium } from "playwright-core";

const CHROMIUM_ARGS = [
  "--headless",
  "--no-sandbox",
  "--disable-gpu",
  "--disable-quic",
  "--no-first-run",
  "--disable-background-networking",
  "--disable-component-update",
  "--disable-sync",
];

function parseArgs(argv) {
  const args = { url: undefined, topics: [], screenshot: undefined, timeout: 90000 };
  for (let i = 0; i < argv.length; i++) {
    const arg = argv[i];
    if (arg === "--topics") args.topics = argv[++i].split(",").filter(Boolean);
    else if (arg === "--screenshot") args.screenshot = argv[++i];
    else if (arg === "--timeout") args.timeout = Number(argv[++i]);
    else if (!args.url) args.url = arg;
    else throw new Error(`unexpected argument ${arg}`);
  }
  if (!args.url) throw new Error("usage: check.mjs URL --topics a,b [--screenshot PNG]");
  return args;
}

async function main() {
  const args = parseArgs(process.argv.slice(2));
  const started = Date.now();
  const origin = new URL(args.url).origin;
  const userDataDir = fs.mkdtempSync(path.join(os.tmpdir(), "amex-chromium-"));
  const context = await chromium.launchPersistentContext(userDataDir, {
    executablePath: process.env.CHROMIUM ?? "/usr/bin/chromium",
    headless: true,
    args: CHROMIUM_ARGS,
    viewport: { width: 1600, height: 1000 },
  });
  const report = {
    topics: [],
    missing: [],
    problems: [],
    pageErrors: [],
    failedRequests: [],
    urdfLoaded: false,
    seconds: 0,
  };
  try {
    const page = context.pages()[0] ?? (await context.newPage());
    page.on("pageerror", (error) => report.pageErrors.push(String(error.message).slice(0, 300)));
    page.on("console", (message) => {
      const text = message.text();
      if (text.startsWith("Player problem")) report.problems.push(text.slice(0, 300));
    });
    page.on("response", (response) => {
      const url = response.url();
      if (!url.startsWith(origin) || url.endsWith("/favicon.ico")) return;
      if (response.status() >= 400) report.failedRequests.push(`${response.status()} ${url}`);
      if (url.includes("/robot/") && url.endsWith(".urdf") && response.ok()) {
        report.urdfLoaded = true;
      }
    });
    await page.goto(args.url);
    const deadline = Date.now() + args.timeout;
    for (const topic of args.topics) {
      const item = page.getByText(topic, { exact: true }).first();
      try {
        await item.waitFor({ timeout: Math.max(deadline - Date.now(), 1000) });
        report.topics.push(topic);
      } catch {
        report.missing.push(topic);
      }
    }
    await page.waitForTimeout(3000); // panels subscribe and load their first messages
    const scrubber = page.locator('[class*="Slider-root"]').first();
    if (await scrubber.count()) {
      const box = await scrubber.boundingBox();
      if (box) await page.mouse.click(box.x + box.width * 0.6, box.y + box.height / 2);
      await page.waitForTimeout(3000);
    }
    if (args.screenshot) await page.screenshot({ path: args.screenshot });
    const tab = page.getByRole("tab", { name: /Problems/ });
    if (await tab.count()) {
      await tab.first().click();
      await page.waitForTimeout(500);
      const panel = page.getByRole("tabpanel");
      const text = (await panel.count()) ? await panel.first().innerText() : "";
      if (text.trim() && !/No problems found/i.test(text)) {
        report.problems.push(`Problems tab: ${text.trim().slice(0, 500)}`);
      }
    }
  } finally {
    await context.close();
    fs.rmSync(userDataDir, { recursive: true, force: true });
  }
  report.seconds = (Date.now() - started) / 1000;
  console.log(JSON.stringify(report, null, 2));
  const ok =
    report.missing.length === 0 &&
    report.problems.length === 0 &&
    report.pageErrors.length === 0 &&
    report.failedRequests.length === 0;
  process.exitCode = ok ? 0 : 1;
}

main().catch((error) => {
  console.error(`check.mjs: ${error.message ?? error}`);
  process.exitCode = 2;
});
