// The last session kept in the browser for "Restore last session" (issue
// #36): stored through session-store.js when the user saves a session and
// when playback pauses or ends, offered back in the message box when the
// page is opened again (e.g. after an accidental reload). A browser that
// refuses to keep it (private mode, quota) only loses the offer. Used by app.js.

import { loadLastSession, storeLastSession } from './session-store.js';

export class LastSession {
  /** `status`: the page's status object (timings, what is kept and offered); `board`: its MessageBoard. */
  constructor(status, board) {
    this.status = status;
    this.board = board;
    /** [text, kind, action] of the offer while it stands (null: none). */
    this.offer = null;
  }

  /** The offer is taken or dismissed. */
  withdraw() {
    this.offer = null;
    this.status.lastSessionOffered = null;
  }

  /** Keeps `bytes` (a session of the sequence `sequenceName`) in IndexedDB. */
  keep(bytes, sequenceName) {
    const name = `${(sequenceName || 'surfel-slam').replace(/[^\w.-]+/g, '_')}.slam`;
    const start = performance.now();
    storeLastSession(bytes, name).then(
      () => {
        this.status.sessionStoreMs = Number((performance.now() - start).toFixed(1));
        this.status.lastSessionStored = { name, bytes: bytes.byteLength };
      },
      (e) => console.warn(`surfel-slam: the last session was not kept in the browser: ${e?.message ?? e}`),
    );
  }

  /** On opening the page: the session kept last, if any, offered back; `restore(name, bytes)` opens it. */
  async offerBack(restore) {
    let last = null;
    try {
      last = await loadLastSession();
    } catch (e) {
      console.warn(`surfel-slam: cannot read the last session kept in the browser: ${e?.message ?? e}`);
    }
    if (!last?.bytes) return;
    const when = new Date(last.savedAt).toLocaleString();
    this.status.lastSessionOffered = last.name;
    this.offer = [
      `last session: ${last.name} (${(last.bytes.byteLength / 1e6).toFixed(1)} MB, kept ${when})`,
      'offer',
      {
        label: 'Restore last session',
        run: () => {
          this.withdraw();
          this.status.shownErrors = this.board.texts();
          const bytes = last.bytes.buffer.slice(last.bytes.byteOffset, last.bytes.byteOffset + last.bytes.byteLength);
          restore(last.name, bytes);
        },
      },
    ];
    this.board.report(...this.offer);
    this.status.shownErrors = this.board.texts();
  }
}
