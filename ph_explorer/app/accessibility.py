"""Accessible names for viser's GUI (a screen reader, Playwright's `get_by_label("A (deg)")`,
`get_by_role("button", name="Curves")`), and a step's results brought into view.

viser 1.1 names checkboxes, dropdowns and buttons by their `<label for=ID>` or text, but a
slider's thumb (role="slider") is left with aria-label="". The server sends each browser a script
once (viser's RunJavascriptMessage, as it sends plotly.js: code goes from the server to the
browser, never the other way) that copies each label onto its thumb and, as a title, onto the
number box beside it; gives a checkbox's label the row's width (an effect's id whole); makes a
folder's title bar a button named by its title (aria-expanded, Enter or Space opens it); names a
notice's close button "Close notice" and the settings icon "Settings"; again whenever the panel
redraws. Method: docs/explorer.md#accessibility.
"""

from __future__ import annotations

import json

import viser
from viser import _messages

NAME_SLIDERS_JS = r"""
(() => {
  if (window.__phExplorerNames) return;
  window.__phExplorerNames = true;
  const nameInputs = () => {
    document.querySelectorAll("label[for]").forEach((label) => {
      const text = label.textContent.trim();
      const target = label.htmlFor ? document.getElementById(label.htmlFor) : null;
      if (!text || !target) return;
      target.querySelectorAll('[role="slider"]').forEach((thumb) => {
        if (thumb.getAttribute("aria-label") !== text) thumb.setAttribute("aria-label", text);
      });
      // A checkbox needs a box's width: its label (an effect's id) takes the rest of the row
      // instead of viser's 7 em column, which breaks a long id mid-word.
      const labelBox = label.parentElement && label.parentElement.parentElement;
      if (target.type === "checkbox" && labelBox && labelBox.style.width !== "calc(100% - 2.5em)") {
        labelBox.style.width = "calc(100% - 2.5em)";
      }
      if (!target.querySelector('[role="slider"]')) return;
      const box = target.parentElement && target.parentElement.querySelector("input[inputmode]");
      if (box && box.title !== text) box.title = text;
    });
  };
  // A folder's title bar (a Paper with cursor:pointer, its title and a chevron) is a button named
  // by its title, expanded or not by its chevron, and opens with Enter or Space as with a click.
  const nameFolders = () => {
    document.querySelectorAll(".mantine-Paper-root > .mantine-Paper-root").forEach((bar) => {
      if (bar.style.cursor !== "pointer" || !bar.querySelector("svg.tabler-icon")) return;
      const title = bar.textContent.trim();
      if (bar.getAttribute("aria-label") !== title) bar.setAttribute("aria-label", title);
      if (bar.getAttribute("role") !== "button") {
        bar.setAttribute("role", "button");
        bar.tabIndex = 0;
        bar.addEventListener("keydown", (event) => {
          if (event.key === "Enter" || event.key === " ") { event.preventDefault(); bar.click(); }
        });
      }
      const open = String(!!bar.querySelector(".tabler-icon-chevron-up"));
      if (bar.getAttribute("aria-expanded") !== open) bar.setAttribute("aria-expanded", open);
    });
  };
  // Icon buttons viser leaves unnamed: a notice's close button, the settings menu.
  const nameIcons = () => {
    document.querySelectorAll(".mantine-Notification-closeButton:not([aria-label])").forEach((b) => b.setAttribute("aria-label", "Close notice"));
    document.querySelectorAll("button:not([aria-label]) .tabler-icon-adjustments").forEach((icon) => {
      icon.closest("button").setAttribute("aria-label", "Settings");
    });
  };
  // Once per frame at most, however many nodes a redraw changes.
  let queued = false;
  const nameAll = () => {
    if (queued) return;
    queued = true;
    requestAnimationFrame(() => { queued = false; nameInputs(); nameFolders(); nameIcons(); });
  };
  new MutationObserver(nameAll).observe(document.body, { childList: true, subtree: true });
  nameAll();
})();
"""


def name_inputs(client: viser.ClientHandle) -> None:
    """Send this browser the script that names its sliders by their labels."""
    # viser has no public call for it; the GUI API sends plotly.js through the same message.
    client.gui._websock_interface.queue_message(_messages.RunJavascriptMessage(source=NAME_SLIDERS_JS))


BRING_INTO_VIEW_JS = r"""
((first, last) => {
  // The control panel's text that a step just wrote: scrolled into view (the panel, not the page),
  // its last line first, then its first, so that a block that fits is wholly in view. The text
  // arrives with the panel's next redraw: looked for during up to 15 s (a busy machine), then kept
  // in view for 5 s from when it was first found, however late that was.
  // The deepest shown element holding the text (a markdown line's <p> or <li>, not its panel).
  const find = (text) => {
    const hits = [...document.querySelectorAll("p, li, td, span, div, strong, em")].filter(
      (e) => e.textContent.includes(text) && e.getClientRects().length
        && ![...e.children].some((child) => child.textContent.includes(text)));
    return hits.length ? hits[hits.length - 1] : null;
  };
  // The last step's text wins: an earlier request still looking for its text (a long verdict
  // arriving late) must not scroll the panel away from what a later step wrote. The text may stand
  // already where an earlier step wrote the same words, and the redraw then replace or move it:
  // it is kept in view for a few seconds, until the reader scrolls, clicks or types.
  const me = (window.phExplorerBringInto = (window.phExplorerBringInto || 0) + 1);
  const start = performance.now();
  let found = null;  // when the text was first found
  let reader = false;
  const events = ["wheel", "touchstart", "pointerdown", "keydown"];
  const readerMoved = () => { reader = true; };
  events.forEach((type) => window.addEventListener(type, readerMoved, { capture: true, passive: true }));
  const attempt = () => {
    const now = performance.now();
    if (window.phExplorerBringInto !== me || reader || now - start > 15000 || (found !== null && now - found > 5000)) {
      events.forEach((type) => window.removeEventListener(type, readerMoved, { capture: true }));
      return;
    }
    setTimeout(attempt, 50);  // the whole panel is searched: a few times a second, not every frame
    const a = find(first), b = last ? find(last) : null;
    if (!a || (last && !b)) return;
    found = found === null ? now : found;
    // The panel that scrolls, and the part of it inside the window (it may reach below it).
    let box = a.parentElement;
    while (box && !(box.scrollHeight > box.clientHeight && /(auto|scroll)/.test(getComputedStyle(box).overflowY))) box = box.parentElement;
    if (!box) return;
    const view = box.getBoundingClientRect();
    const top = Math.max(view.top, 0) + 8, bottom = Math.min(view.bottom, window.innerHeight) - 8;
    const from = a.getBoundingClientRect().top, to = (b || a).getBoundingClientRect().bottom;
    let delta = to > bottom ? to - bottom : 0;  // the last line up into view ...
    if (from - delta < top) delta = from - top;  // ... but never the first out at the top
    if (Math.abs(delta) >= 1) box.scrollTop += delta;
  };
  attempt();
})(%s, %s);
"""


def bring_into_view(gui: viser.GuiApi, first: str, last: str | None = None) -> None:
    """Scroll this browser's control panel so that the text a step just wrote (from the line holding
    `first` to the one holding `last`) is in view, wherever the panels left it (issue 31, item 4)."""
    source = BRING_INTO_VIEW_JS % (json.dumps(first), json.dumps(last))
    gui._websock_interface.queue_message(_messages.RunJavascriptMessage(source=source))
