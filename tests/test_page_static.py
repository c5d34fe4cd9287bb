"""The web page's files read as text, where no browser is needed (`tests/test_browser.py` drives
the page itself, and skips where no Chromium is installed): the references between its
elements, and the small-screen layout its stylesheet asks for."""

from __future__ import annotations

import re
from html.parser import HTMLParser
from importlib import resources


def static(name: str) -> str:
    return resources.files("lookfeel.serve").joinpath("static", name).read_text("utf-8")


class Elements(HTMLParser):
    """Every element's attributes by its id, and the role each id'd element has."""

    def __init__(self) -> None:
        super().__init__()
        self.by_id: dict[str, dict[str, str | None]] = {}

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        named = dict(attrs)
        if named.get("id"):
            self.by_id[str(named["id"])] = {"tag": tag, **named}


def test_the_page_refers_only_to_its_own_elements_and_has_an_alert_region():
    page = Elements()
    page.feed(static("index.html"))
    ids = page.by_id
    referred = [
        (name, ref)
        for name, attrs in ids.items()
        for key in ("aria-describedby", "aria-labelledby")
        for ref in (attrs.get(key) or "").split()
    ]
    assert ("files", "files-hint") in referred and ("query", "query-title") in referred
    assert all(ref in ids for _, ref in referred), referred
    # Errors are read out at once (role="alert"), the rest politely (role="status").
    assert ids["error"]["role"] == "alert" and ids["status"]["role"] == "status"


def test_on_a_phone_each_card_is_one_column():
    """WCAG 1.4.10 (reflow): below 560 px a card's images go under its text, not beside it
    (beside it they spill past a 360 px screen)."""
    css = static("style.css")
    (block,) = re.findall(r"@media \(max-width: (\d+)px\) \{(.*?)\n\}", css, re.S)
    width, rules = int(block[0]), block[1]
    assert width >= 360
    (columns,) = re.findall(r"\.fabric \{[^}]*grid-template-columns: ([^;]+);", rules)
    assert columns in ("1fr", "minmax(0, 1fr)")
