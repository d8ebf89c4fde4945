// The page's one place for problems: a box over the map canvas (always in
// the viewport, whatever the panel's scroll), newest message first. A new
// run, a successful Apply or a newly opened sequence clears what was shown:
// those messages described a run that is gone.

/** How many messages the box shows; older ones are counted, not shown. */
const SHOWN = 4;

export class MessageBoard {
  /** `el`: {box, text, close} elements (#message, #message-text, #message-close). */
  constructor(el) {
    this.el = el;
    this.shown = []; // current messages, newest first
    this.older = 0; // messages beyond SHOWN since the last clear
    el.close.addEventListener('click', () => this.clear());
  }

  /**
   * Shows `text` first, above the earlier messages of this run; `kind`:
   * 'error', 'warning' or 'offer'; `action`: {label, run} adds a button that
   * runs it (and removes the message).
   */
  report(text, kind = 'error', action = null) {
    this.shown.unshift({ text, kind, action });
    if (this.shown.length > SHOWN) {
      this.shown.length = SHOWN;
      this.older++;
    }
    this.render();
  }

  /** The texts shown, newest first. */
  texts() {
    return this.shown.map((m) => m.text);
  }

  /** Removes every message (a new run or a successful change of settings). */
  clear() {
    this.shown = [];
    this.older = 0;
    this.render();
  }

  render() {
    const { box, text } = this.el;
    const lines = this.shown.map((m, i) => {
      const li = document.createElement('li');
      li.textContent = m.text;
      li.className = i === 0 ? `${m.kind} latest` : m.kind;
      if (m.action) {
        const button = document.createElement('button');
        button.type = 'button';
        button.textContent = m.action.label;
        button.addEventListener('click', () => {
          this.shown = this.shown.filter((x) => x !== m);
          this.render();
          m.action.run();
        });
        li.append(' ', button);
      }
      return li;
    });
    if (this.older > 0) {
      const li = document.createElement('li');
      li.className = 'older';
      li.textContent = `(${this.older} earlier not shown)`;
      lines.push(li);
    }
    text.replaceChildren(...lines);
    box.hidden = this.shown.length === 0;
  }
}
