"""Accessible names for viser's GUI inputs, so that a browser (a screen reader, Playwright's
`get_by_label("A (deg)")`) finds each slider by the label written beside it.

viser 1.1 writes a `<label for=ID>` beside every input; checkboxes, dropdowns and buttons are
named by it (or by their text), but a slider's ID sits on Mantine's slider root, a <div> that a
label cannot name, and its thumb (role="slider") is left with aria-label="". The server sends each
browser this script once (viser's own RunJavascriptMessage, the message it sends plotly.js with:
code goes from the server to the browser, never the other way). It copies each label's text onto
the thumb it stands for, and onto the number box beside it as a title (a name for the box, without
making `get_by_label` ambiguous), again whenever the panel redraws.
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
  new MutationObserver(nameInputs).observe(document.body, { childList: true, subtree: true });
  nameInputs();
})();
"""


def name_inputs(client: viser.ClientHandle) -> None:
    """Send this browser the script that names its sliders by their labels."""
    # viser has no public call for it; the GUI API sends plotly.js through the same message.
    client.gui._websock_interface.queue_message(_messages.RunJavascriptMessage(source=NAME_SLIDERS_JS))
