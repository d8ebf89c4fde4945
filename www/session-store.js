// The last session, kept in the browser's IndexedDB (issue #36): stored when
// the user saves a session and when playback pauses or ends, offered back
// ("Restore last session") when the page is opened again, e.g. after an
// accidental reload. One record, replaced each time; a browser that refuses
// (private mode, quota) only loses the offer. Used by app.js.

const DB = 'surfel-slam';
const STORE = 'sessions';
const KEY = 'last';

function openDb() {
  return new Promise((resolve, reject) => {
    const req = indexedDB.open(DB, 1);
    req.onupgradeneeded = () => req.result.createObjectStore(STORE);
    req.onsuccess = () => resolve(req.result);
    req.onerror = () => reject(req.error);
  });
}

async function withStore(mode, use) {
  const db = await openDb();
  try {
    return await new Promise((resolve, reject) => {
      const tx = db.transaction(STORE, mode);
      const req = use(tx.objectStore(STORE));
      tx.oncomplete = () => resolve(req.result);
      tx.onerror = () => reject(tx.error);
      tx.onabort = () => reject(tx.error);
    });
  } finally {
    db.close();
  }
}

/** Keeps `bytes` (a session file) as the last session, named `name` (the .slam file name). */
export const storeLastSession = (bytes, name) =>
  withStore('readwrite', (s) => s.put({ bytes, name, savedAt: Date.now() }, KEY));

/** `{bytes, name, savedAt}` of the last session kept, or null. */
export async function loadLastSession() {
  return (await withStore('readonly', (s) => s.get(KEY))) ?? null;
}
