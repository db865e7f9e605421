"""Which licence a source's own file states, and whether this package may ship it.

A licence is read from the text of a file that comes with the source (an archive's
``LICENSE.TXT``, a model's Blend Swap licence file, a wheel's ``LICENSE``), never inferred from
the licence of the package that happens to carry it. A text that states no licence this module
recognises is treated as unstated: such a file cannot ship.
"""

from __future__ import annotations

import re

# What may ship (DESIGN.md, "Looks"): never NC, ND, SA, GPL, or of unstated origin.
ALLOWED = ("CC0-1.0", "CC-BY-3.0", "CC-BY-3.0-US", "MIT", "Apache-2.0")
NAMES = {
    "CC0-1.0": "Creative Commons Zero 1.0 Universal (public domain dedication)",
    "CC-BY-3.0": "Creative Commons Attribution 3.0 Unported",
    "CC-BY-3.0-US": "Creative Commons Attribution 3.0 United States",
    "MIT": "MIT License",
    "Apache-2.0": "Apache License 2.0",
}
URIS = {
    "CC0-1.0": "https://creativecommons.org/publicdomain/zero/1.0/",
    "CC-BY-3.0": "https://creativecommons.org/licenses/by/3.0/",
    "CC-BY-3.0-US": "https://creativecommons.org/licenses/by/3.0/us/",
    "MIT": "https://opensource.org/license/mit",
    "Apache-2.0": "https://www.apache.org/licenses/LICENSE-2.0",
}

_CC_URI = re.compile(
    r"creativecommons\.org/(?:licenses|publicdomain)/([a-z-]+)/(\d\.\d)(?:/([a-z]{2})\b)?", re.I
)
_CC_ZERO_CHOOSER = re.compile(r"creativecommons\.org/choose/zero", re.I)
_CC_NAME = re.compile(
    r"Creative\s+Commons\s+(Attribution(?:[\s-]+(?:Non-?Commercial|Share-?Alike|No-?Derivs|"
    r"No-?Derivatives))*)\s+(\d\.\d)(\s+United\s+States)?",
    re.I,
)
_CC_ZERO_NAME = re.compile(r"Creative\s+Commons\s+Zero|\bCC0\b|\bCC-0\b", re.I)
_PARTS = {"noncommercial": "NC", "sharealike": "SA", "noderivs": "ND", "noderivatives": "ND"}


def spdx_of_cc(kind: str, version: str, jurisdiction: str | None) -> str:
    """``by-nc-sa``, ``4.0`` -> ``CC-BY-NC-SA-4.0``; ``zero``, ``1.0`` -> ``CC0-1.0``."""
    if kind.lower() == "zero":
        return f"CC0-{version}"
    tail = f"-{jurisdiction.upper()}" if jurisdiction else ""
    return f"CC-{kind.upper()}-{version}{tail}"


def identify(text: str) -> str | None:
    """The SPDX id of the licence a licence text states, or None. The words of the text (HTML
    tags stripped) come first, the first licence they name; links only where they name none
    (a page's badge may link another deed than the one its words state)."""
    words = re.sub(r"<[^>]+>", " ", text)
    return _named(words) or _linked(text)


def _named(text: str) -> str | None:
    found: list[tuple[int, str]] = []
    if m := _CC_NAME.search(text):
        phrase = m.group(1).lower()
        for spaced in ("non-commercial", "share-alike", "no-derivs", "no-derivatives"):
            phrase = phrase.replace(spaced, spaced.replace("-", ""))
        kind = "-".join(["by"] + [_PARTS[w].lower() for w in re.split(r"[\s-]+", phrase)[1:]])
        found.append((m.start(), spdx_of_cc(kind, m.group(2), "us" if m.group(3) else None)))
    if m := _CC_ZERO_NAME.search(text):
        found.append((m.start(), "CC0-1.0"))
    if "Permission is hereby granted, free of charge" in text:
        found.append((text.index("Permission is hereby granted"), "MIT"))
    if m := re.search(r"Apache License,?\s+Version 2\.0", text):
        found.append((m.start(), "Apache-2.0"))
    return min(found)[1] if found else None


def _linked(text: str) -> str | None:
    found: list[tuple[int, str]] = []
    if m := _CC_URI.search(text):
        found.append((m.start(), spdx_of_cc(*m.groups())))
    if m := _CC_ZERO_CHOOSER.search(text):
        found.append((m.start(), "CC0-1.0"))
    return min(found)[1] if found else None


def check(spdx: str | None, what: str, where: str) -> str:
    """``spdx`` if this package may ship it; else a ValueError naming the file and the licence."""
    if spdx is None:
        raise ValueError(f"{what}: {where} states no licence this package recognises; "
                         f"expected one of {', '.join(ALLOWED)}")  # fmt: skip
    if spdx not in ALLOWED:
        raise ValueError(f"{what}: {where} states {spdx}, which this package may not ship; "
                         f"expected one of {', '.join(ALLOWED)}")  # fmt: skip
    return spdx


# Files known to carry no licence this package may ship, whatever a manifest says of them:
# mani-skill's robot meshes (fetch_ros's fetch_description, CC-BY-NC-SA-4.0) and its
# environment maps (no stated origin).
UNSHIPPABLE = ("mani_skill/", "mani-skill/", "fetch_description", "robots/fetch/", "default.hdr")
CREDITED = ("title", "author", "url")  # what an attribution licence asks to be named


def audit(manifest: dict[str, dict], sources: set[str]) -> list[str]:
    """Every way a manifest's entries fall short of what may ship, one line each: a licence
    outside :data:`ALLOWED`, no file that states it, a source that is not one of ``sources``
    (the selection's and the project's own), a file of known unshippable origin, a CC-BY work
    without its title, author or origin."""
    problems = []
    for rel, entry in sorted(manifest.items()):
        if not entry.get("sources"):
            problems.append(f"{rel}: names no source")
        for src in entry.get("sources", []):
            where = f"{rel} ({src.get('source')}: {src.get('model')})"
            if src.get("licence") not in ALLOWED:
                problems.append(f"{where}: licence {src.get('licence')} may not ship")
            if not src.get("licence_file"):
                problems.append(f"{where}: no file stating its licence")
            if src.get("source") not in sources:
                problems.append(f"{where}: an unknown source")
            if any(bad in str(src.get("model", "")) for bad in UNSHIPPABLE):
                problems.append(f"{where}: derived from a file of unshippable origin")
            if str(src.get("licence", "")).startswith("CC-BY"):
                missing = [k for k in CREDITED if not src.get(k)]
                if missing:
                    problems.append(f"{where}: CC-BY without its {', '.join(missing)}")
    return problems
