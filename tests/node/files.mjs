// File listing shared by the Node scripts: relative names, '/' separated,
// 3 levels deep, hidden entries skipped (like the CLI's listing).
import { readdir } from 'node:fs/promises';
import path from 'node:path';

export async function listFiles(dir, rel = '', depth = 2, out = []) {
  for (const entry of await readdir(path.join(dir, rel), { withFileTypes: true })) {
    if (entry.name.startsWith('.')) continue;
    const child = rel ? `${rel}/${entry.name}` : entry.name;
    if (entry.isDirectory()) {
      if (depth > 0) await listFiles(dir, child, depth - 1, out);
    } else {
      out.push(child);
    }
  }
  return out;
}
