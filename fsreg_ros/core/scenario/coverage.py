"""What a lexicon can say of a scenario's properties: one warning for the rest, and a lexicon skeleton for them.

A property the lexicon lists, or an ``attribute=value`` property with a word value (said
by the default of :func:`fsreg_ros.core.lexicon.attribute_entry`), is said in words.  Any other is said
as its name ("the place with shelf"): :func:`unsayable` lists them per domain,
:func:`coverage_warning` says so in one line at start (``fsreg-sim``, ``fsreg-graph``,
``fsreg-up``), and :func:`lexicon_template` writes the skeleton of a lexicon file for
them (``fsreg-sim S --lexicon-template OUT.yaml``), to be filled in and given back with
``--lexicon OUT.yaml``.
"""

from __future__ import annotations

from typing import Optional

import yaml

from ..lexicon.lexicon import DEFAULT_DOMAIN_NOUNS, Lexicon
from .model import Scenario

#: How many property names the warning shows before "...".
SHOWN = 12


def unsayable(lexicon: Lexicon, scenario: Scenario) -> dict[str, list[str]]:
    """Return, per domain (scenario order), the properties the lexicon cannot say (preference order)."""
    out: dict[str, list[str]] = {}
    for domain, spec in scenario.domains.items():
        missing = [p for p in spec.preference if not lexicon.can_say(p)]
        if missing:
            out[domain] = missing
    return out


def coverage_warning(lexicon: Lexicon, scenario: Scenario) -> Optional[str]:
    """Return one line naming the properties the lexicon cannot say (None if it can say them all)."""
    missing = unsayable(lexicon, scenario)
    if not missing:
        return None
    total = sum(len(props) for props in missing.values())
    names = [f"{p} ({d})" for d, props in missing.items() for p in props]
    shown = ", ".join(names[:SHOWN]) + (f", ... ({total - SHOWN} more)" if total > SHOWN else "")
    return (f"the lexicon has no words for {total} propert{'y' if total == 1 else 'ies'}, said as "
            f"{'its name' if total == 1 else 'their names'} (e.g. \"with {missing_example(lexicon, missing)}\"): "
            f"{shown}; write a lexicon for them with --lexicon-template OUT.yaml and give it with --lexicon OUT.yaml")


def missing_example(lexicon: Lexicon, missing: dict[str, list[str]]) -> str:
    """Return how the first property the lexicon cannot say is said after "with"."""
    first = next(iter(missing.values()))[0]
    return lexicon.entry(first).post_modifier()


def lexicon_template(lexicon: Lexicon, scenario: Scenario, source: str = "the scenario") -> str:
    """Return the text of a lexicon file with one entry to fill in per property the lexicon cannot say.

    Each entry is given ``words`` (its name, read as words) so the file is valid as it
    stands; the comments say what else an entry may give.  Domains the lexicon does not
    know get a ``noun`` (the head noun when no property gives one).
    """
    missing = unsayable(lexicon, scenario)
    total = sum(len(props) for props in missing.values())
    lines = [
        f"# Lexicon for {source}: how to say the {total} propert{'y' if total == 1 else 'ies'} the built-in lexicon",
        "# cannot say (written by --lexicon-template).  Each entry may give (config/lexicon.yaml has the format):",
        "#   noun: WORD        it heads the description: 'the shelf'",
        "#   adjective: WORD   a pre-modifier: 'the red ...', with order: N (10 quality, 20 size, 30 age,",
        "#                     40 shape, 50 colour, 60 orientation)",
        "#   words: WORDS      after 'with' (the default below), with article: a / an",
        "#   phrases: [...]    other ways a human says it",
        "# Then: fsreg-sim SCENARIO --lexicon THIS_FILE (fsreg-graph and fsreg-up take --lexicon too).",
    ]
    if not missing:
        lines.append("# The lexicon can say every property of the scenario: nothing to add.")
        return "\n".join(lines) + "\n{}\n"
    domains: dict = {}
    for domain, props in missing.items():
        block: dict = {"properties": props}
        if lexicon.noun_for(domain) == lexicon.default_noun and domain not in DEFAULT_DOMAIN_NOUNS:
            block = {"noun": lexicon.default_noun, **block}
        domains[domain] = block
    properties = {p: {"words": lexicon.entry(p).post_modifier()} for props in missing.values() for p in props}
    body = yaml.safe_dump({"domains": domains, "properties": properties}, sort_keys=False, allow_unicode=True,
                          default_flow_style=False)
    return "\n".join(lines) + "\n" + body
