// Headless Chromium for the browser tests and bench/web: Debian's chromium (or
// $LIGHTLINK_CHROMIUM) driven by playwright-core, WebGL 2 through SwiftShader (no GPU), a
// fresh profile and no network of its own.
import fs from 'node:fs';
import { chromium } from 'playwright-core';

// The Chromium binary, or null when none is installed (the tests then skip with 77).
export function findChromium() {
  return [process.env.LIGHTLINK_CHROMIUM, '/usr/bin/chromium', '/usr/bin/chromium-browser'].find((p) => p && fs.existsSync(p)) ?? null;
}

export function launchBrowser(executablePath) {
  return chromium.launch({
    executablePath, headless: true,
    args: ['--no-sandbox', '--disable-gpu', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--disable-quic',
           '--no-first-run', '--disable-background-networking', '--disable-component-update', '--disable-sync'],
  });
}
