"""Accessible names for viser's GUI inputs, folders and icon buttons, so that a browser (a screen
reader, Playwright's `get_by_label("A (deg)")`, `get_by_role("button", name="Curves")`) finds each
control by the label written beside it.

viser 1.1 writes a `<label for=ID>` beside every input; checkboxes, dropdowns and buttons are
named by it (or by their text), but a slider's ID sits on Mantine's slider root, a <div> that a
label cannot name, and its thumb (role="slider") is left with aria-label="". The server sends each
browser this script once (viser's own RunJavascriptMessage, the message it sends plotly.js with:
code goes from the server to the browser, never the other way). It copies each label's text onto
the thumb it stands for, and onto the number box beside it as a title (a name for the box, without
making `get_by_label` ambiguous), again whenever the panel redraws. A folder's title bar becomes a
button named by its title (aria-expanded from its chevron; Enter or Space opens it); a notice's
close button is "Close notice", the settings icon "Settings".
"""

from __future__ import annotations

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
