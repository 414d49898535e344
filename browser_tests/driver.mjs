// A small line-protocol driver for Debian's chromium through playwright-core,
// used by python_tests/test_preview_browser.py (and scripts/bench_preview).
//
// stdin: one JSON command per line; stdout: one JSON reply per line
// ({"ok": true, ...} or {"ok": false, "error": "..."}). Commands:
//   launch                        → {pid, browser_pids}
//   goto {url, init}              → opens the page (console errors are collected;
//                                   `init`: a script run before the page's own)
//   eval {js}                     → {value} of the expression (promises awaited)
//   wait {js, timeout}            → waits until the expression is truthy
//   drag {selector, dx, dy, steps, shift}
//   click {selector}
//   screenshot {selector, path}
//   console {clear}               → {errors: [...]} collected so far (`clear`:
//                                   and forget them)
//   quit
import { chromium } from 'playwright-core';
import { mkdtempSync, rmSync, readdirSync, readFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { createInterface } from 'node:readline';

const ARGS = [
  '--headless',
  '--no-sandbox',
  '--enable-unsafe-swiftshader',
  '--disable-gpu',
  '--disable-background-networking',
  '--disable-component-update',
  '--disable-sync',
  '--no-first-run',
];

let context = null;
let page = null;
let userDataDir = null;
const errors = [];

// Child processes of this driver (the browser), for the caller to stop by pid.
function childPids() {
  const out = [];
  for (const d of readdirSync('/proc')) {
    if (!/^\d+$/.test(d)) continue;
    try {
      const stat = readFileSync(`/proc/${d}/stat`, 'utf8');
      const ppid = Number(stat.slice(stat.lastIndexOf(')') + 2).split(' ')[1]);
      if (ppid === process.pid) out.push(Number(d));
    } catch {
      // gone already
    }
  }
  return out;
}

const commands = {
  async launch() {
    userDataDir = mkdtempSync(join(tmpdir(), 'painterly-chromium-'));
    context = await chromium.launchPersistentContext(userDataDir, {
      executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
      headless: true,
      args: ARGS,
      viewport: { width: 1200, height: 760 },
      deviceScaleFactor: 1,
    });
    return { pid: process.pid, browser_pids: childPids() };
  },
  async goto({ url, init }) {
    if (page) await page.close();
    page = await context.newPage();
    if (init) await page.addInitScript(init);
    page.on('console', (m) => {
      if (m.type() === 'error') errors.push(`console: ${m.text()}`);
    });
    page.on('pageerror', (e) => errors.push(`page error: ${e.message}`));
    page.on('requestfailed', (r) => errors.push(`request failed: ${r.url()} ${r.failure()?.errorText}`));
    await page.goto(url);
    return {};
  },
  async eval({ js }) {
    return { value: await page.evaluate(js) };
  },
  // Polls with page.evaluate: waitForFunction evaluates strings with eval(),
  // which the page's Content-Security-Policy (rightly) forbids.
  async wait({ js, timeout }) {
    const deadline = Date.now() + (timeout ?? 20000);
    for (;;) {
      if (await page.evaluate(js)) return {};
      if (Date.now() > deadline) throw new Error(`timed out waiting for ${js}`);
      await new Promise((r) => setTimeout(r, 20));
    }
  },
  async drag({ selector, dx, dy, steps, shift }) {
    const box = await page.locator(selector).boundingBox();
    const x = box.x + box.width / 2;
    const y = box.y + box.height / 2;
    if (shift) await page.keyboard.down('Shift');
    await page.mouse.move(x, y);
    await page.mouse.down();
    await page.mouse.move(x + dx, y + dy, { steps: steps ?? 8 });
    await page.mouse.up();
    if (shift) await page.keyboard.up('Shift');
    return {};
  },
  async click({ selector }) {
    await page.locator(selector).click();
    return {};
  },
  async screenshot({ selector, path }) {
    await page.locator(selector).screenshot({ path });
    return {};
  },
  async console({ clear } = {}) {
    const out = errors.slice();
    if (clear) errors.length = 0;
    return { errors: out };
  },
  async quit() {
    if (context) await context.close();
    context = null;
    if (userDataDir) rmSync(userDataDir, { recursive: true, force: true });
    return {};
  },
};

const rl = createInterface({ input: process.stdin });
for await (const line of rl) {
  if (!line.trim()) continue;
  let reply;
  let cmd = null;
  try {
    const msg = JSON.parse(line);
    cmd = msg.cmd;
    const f = commands[cmd];
    if (!f) throw new Error(`unknown command ${cmd}`);
    reply = { ok: true, ...(await f(msg)) };
  } catch (e) {
    reply = { ok: false, error: String(e && e.stack ? e.stack : e) };
  }
  process.stdout.write(JSON.stringify(reply) + '\n');
  if (cmd === 'quit') break;
}
process.exit(0);
