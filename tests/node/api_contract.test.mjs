// The JS API's three descriptions agree with the built module: the config
// keys the parser accepts (its unknown-key error lists them, and each must be
// read: a value of the wrong type is refused naming `config.<key>`), the
// `SlamConfig` typing in pkg/surfel_slam.d.ts and the "Config keys" table of
// docs/js-api.md; and the fields of a real frame report, the `FrameReport`
// typing, the "Frame report" table and the npm README's pushFrame row (the
// README's config row may list a few keys, but only real ones). See
// docs/js-api.md, "Adding a config key".
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { existsSync, readFileSync } from 'node:fs';
import path from 'node:path';
import { loadPackage, PKG, ROOT } from './long_run.mjs';

const CLIP = path.join(ROOT, 'www/sample/tum_fr3_teddy_clip');
const skip = existsSync(path.join(PKG, 'surfel_slam.js')) ? false : `${PKG} is not built: run scripts/build.sh`;

/** The body of `export interface name { ... }` in TypeScript text. */
function interfaceBody(ts, name) {
  const start = ts.indexOf(`export interface ${name} {`);
  assert.ok(start >= 0, `interface ${name} not in the typings`);
  let depth = 0;
  for (let i = ts.indexOf('{', start); i < ts.length; i++) {
    if (ts[i] === '{') depth++;
    else if (ts[i] === '}' && --depth === 0) return ts.slice(ts.indexOf('{', start) + 1, i);
  }
  throw new Error(`interface ${name} is not closed`);
}

/** Field names of an interface body, nested object types as `outer.inner`. */
function tsFields(body, prefix = '') {
  const text = body.replace(/\/\*[\s\S]*?\*\//g, '').replace(/\/\/.*$/gm, '');
  const out = [];
  let i = 0;
  while (i < text.length) {
    const m = /^\s*([A-Za-z_$][\w$]*)\??\s*:\s*/.exec(text.slice(i));
    if (!m) {
      i++;
      continue;
    }
    i += m[0].length;
    if (text[i] === '{') {
      let depth = 0;
      const open = i;
      for (; i < text.length; i++) {
        if (text[i] === '{') depth++;
        else if (text[i] === '}' && --depth === 0) break;
      }
      out.push(...tsFields(text.slice(open + 1, i), `${prefix}${m[1]}.`));
      i++;
    } else {
      out.push(prefix + m[1]);
      // Skip the type up to the end of the member (brackets may hold ';' or ',').
      let depth = 0;
      for (; i < text.length; i++) {
        const c = text[i];
        if ('[({<'.includes(c)) depth++;
        else if (')]}>'.includes(c)) depth--;
        else if ((c === ';' || c === '\n') && depth === 0) break;
      }
    }
  }
  return out;
}

/** The first column (`name` in backticks) of the table under `## heading`. */
function docTable(md, heading) {
  const start = md.indexOf(`\n## ${heading}\n`);
  assert.ok(start >= 0, `docs/js-api.md has no "## ${heading}" section`);
  const rest = md.slice(start + 1);
  const next = rest.indexOf('\n## ');
  const section = next >= 0 ? rest.slice(0, next) : rest;
  return [...section.matchAll(/^\| `([^`]+)` \|/gm)].map((m) => m[1]);
}

/** Field paths of a plain JS object (nested plain objects as `outer.inner`). */
function objectFields(value, prefix = '') {
  return Object.entries(value).flatMap(([k, v]) =>
    v && typeof v === 'object' && Object.getPrototypeOf(v) === Object.prototype
      ? objectFields(v, `${prefix}${k}.`)
      : [prefix + k],
  );
}

/**
 * Field paths of a README object sketch like `{ a, b: 'x' | 'y', c (m), d: { e, f } (ms) }`
 * (`text` starts at its `{`): the first name of each comma-separated element.
 */
function sketchFields(text, prefix = '') {
  const plain = text.replace(/'[^']*'/g, "''");
  const name = (element) => /^\s*([A-Za-z_$][\w$]*)/.exec(element)?.[1];
  const out = [];
  let depth = 0; // of () and []
  let element = ''; // the current element's text; null once a nested object took it
  for (let i = 1; i < plain.length; i++) {
    const c = plain[i];
    if (depth === 0 && c === '{') {
      const open = i;
      for (let braces = 0; i < plain.length; i++) {
        if (plain[i] === '{') braces++;
        else if (plain[i] === '}' && --braces === 0) break;
      }
      out.push(...sketchFields(plain.slice(open, i + 1), `${prefix}${name(element)}.`));
      element = null;
      continue;
    }
    if ('(['.includes(c)) depth++;
    else if (')]'.includes(c)) depth--;
    if (depth === 0 && (c === ',' || c === '}')) {
      if (element !== null && name(element)) out.push(prefix + name(element));
      element = '';
      if (c === '}') break;
    } else if (element !== null) {
      element += c;
    }
  }
  return out;
}

/** The README API table's cell after the row whose first cell starts with `call`. */
function readmeRow(md, call) {
  const line = md.split('\n').find((l) => l.startsWith(`| \`${call}`));
  assert.ok(line, `pkg-config/README.md has no row for ${call}`);
  return line;
}

const sorted = (list) => [...list].sort();
function sameSet(actual, expected, what) {
  assert.equal(new Set(actual).size, actual.length, `${what}: listed twice: ${actual}`);
  assert.deepEqual(sorted(actual), sorted(expected), what);
}

test('tsFields reads nested members and skips comments', () => {
  const body = `
  /** a: {not: this} */
  a?: number; b: 'x' | 'y';
  // c: no
  counts: { d: number; e: [number, number] };
  f: Float64Array;`;
  assert.deepEqual(tsFields(body), ['a', 'b', 'counts.d', 'counts.e', 'f']);
  const sketch = "{ a, b: 'x, y' | 'z', c (m, [1, 2]), counts: { d, e }, timings: { g } (ms), h }";
  assert.deepEqual(sketchFields(sketch), ['a', 'b', 'c', 'counts.d', 'counts.e', 'timings.g', 'h']);
});

test('config keys: parser, typings and docs agree', { skip }, async () => {
  const m = await loadPackage();
  const ts = readFileSync(path.join(PKG, 'surfel_slam.d.ts'), 'utf8');
  const md = readFileSync(path.join(ROOT, 'docs/js-api.md'), 'utf8');

  let message = '';
  try {
    new m.Slam({ preset: 'tum-fr3', notAConfigKey: 1 });
  } catch (e) {
    message = e.message;
  }
  const listed = /known fields: (.*)$/.exec(message);
  assert.ok(listed, `the unknown-key error lists the known keys: ${message}`);
  const parser = listed[1].split(', ');

  const typed = tsFields(interfaceBody(ts, 'SlamConfig'));
  const documented = docTable(md, 'Config keys');
  sameSet(typed, parser, 'SlamConfig typing vs the keys the parser accepts');
  sameSet(documented, parser, 'docs/js-api.md "Config keys" vs the keys the parser accepts');
  const row = readmeRow(readFileSync(path.join(ROOT, 'pkg-config/README.md'), 'utf8'), 'new Slam(config)');
  const readme = sketchFields(row.slice(row.indexOf('`{') + 1));
  assert.ok(readme.length >= 5, `README config keys: ${readme}`);
  for (const key of readme) assert.ok(parser.includes(key), `pkg-config/README.md names config key ${key}, which the parser does not accept`);

  // Each listed key is read: a value of no accepted type is refused by name.
  for (const key of parser) {
    assert.throws(() => new m.Slam({ preset: 'tum-fr3', [key]: Symbol('wrong') }), new RegExp(`config\\.${key} must be`), key);
  }
});

test('frame report: a real report, the typing and the docs agree', { skip }, async () => {
  const m = await loadPackage();
  const ts = readFileSync(path.join(PKG, 'surfel_slam.d.ts'), 'utf8');
  const md = readFileSync(path.join(ROOT, 'docs/js-api.md'), 'utf8');
  const first = (file) =>
    readFileSync(path.join(CLIP, file), 'utf8')
      .split('\n')
      .find((l) => l.trim() && !l.startsWith('#'))
      .split(/\s+/)[1];
  const colour = new Uint8Array(readFileSync(path.join(CLIP, first('rgb.txt'))));
  const depth = new Uint8Array(readFileSync(path.join(CLIP, first('depth.txt'))));
  const slam = new m.Slam({ preset: 'tum-fr3' });
  try {
    const report = slam.pushFrame(colour, depth, 0);
    const actual = objectFields(report);
    sameSet(tsFields(interfaceBody(ts, 'FrameReport')), actual, 'FrameReport typing vs a real report');
    sameSet(docTable(md, 'Frame report'), actual, 'docs/js-api.md "Frame report" vs a real report');
    const row = readmeRow(readFileSync(path.join(ROOT, 'pkg-config/README.md'), 'utf8'), 'slam.pushFrame(');
    sameSet(sketchFields(row.slice(row.indexOf('`{') + 1)), actual, 'pkg-config/README.md pushFrame row vs a real report');
    // The recording ended after one frame: nothing old to look the frame up in.
    const end = slam.finish();
    const finished = objectFields(end);
    assert.equal(end.looked, false);
    sameSet(tsFields(interfaceBody(ts, 'FinishReport')), finished, 'FinishReport typing vs a real one');
    const finishRow = readmeRow(readFileSync(path.join(ROOT, 'pkg-config/README.md'), 'utf8'), 'slam.finish(');
    sameSet(sketchFields(finishRow.slice(finishRow.indexOf('`{') + 1)), finished, 'pkg-config/README.md finish row vs a real one');
    const docLine = md.split('\n').find((l) => l.startsWith('slam.finish()'));
    assert.ok(docLine, 'docs/js-api.md has no slam.finish() line');
    sameSet(sketchFields(docLine.slice(docLine.indexOf('{'))), finished, 'docs/js-api.md finish line vs a real one');
  } finally {
    slam.free();
  }
});
