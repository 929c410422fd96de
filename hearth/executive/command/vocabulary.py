"""What the robot can be asked for: missions (with parameters and utterance templates from
the mission files) and the known objects, places and rooms (from the map).

HOBBIT's MMUI fetches the names of known objects and places at start-up and again on each
F_UPDATE, and inserts them into its speech grammar; here the vocabulary subscribes to the map
and bumps ``revision`` on every change, so a dialogue layer re-reads it when the revision it
holds is stale (the event stream also announces each new revision).

Utterance templates (top-level ``utterances:`` in a mission file)::

    utterances:
      - "bring me (the|my|a) {object:thing}"      # {parameter:class}
      - "turn off (the) {oven:appliance}"
      - {say: "I am going out", params: {presence: away}}

``(a|b)`` is an optional group of alternative words, ``(the)`` one optional word; ``{name}``
takes the words for parameter ``name`` (at least one); ``:class`` says which map nodes the
words must name (``SLOT_CLASSES``). A node_id parameter without a class names any node.

Matching is a table over (template token, word position), filled backwards, then read
forwards taking at each token the choice a backtracking regular expression would try first
(an optional group's alternatives in order, then skipping it; a slot's shortest words):
the same answer as the regular expression the templates were once compiled to, in time
linear in the template's tokens times the utterance's words. (That regular expression
backtracked exponentially: a template of 60 optional groups froze the server on one
22-word command, issue 44.) Templates are also bounded when loaded (``MAX_TEMPLATE_CHARS``,
``MAX_TEMPLATE_TOKENS``).
"""
from __future__ import annotations

import re
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from hearth.executive.errors import MissionError
from hearth.executive.missionfile import Mission
from hearth.executive.missionfile_types import plain
from hearth.executive.missionfile_yaml import LineDict, LineList, load_yaml

#: slot class -> the map node kinds its words may name
SLOT_CLASSES: dict[str, tuple[str, ...]] = {
    "thing": ("SmallObject",),
    "furniture": ("LargeObject", "LargeArticulatedObject"),
    "appliance": ("LargeArticulatedObject",),
    "room": ("Room",),
    "place": ("Room", "LargeObject", "LargeArticulatedObject"),
    "part": ("Part",),
    "knob": ("Knob",),
    "switch": ("Switch",),
    "node": (),        # any kind
}

#: A template's length and its tokens (words, groups, slots): what a person says in one
#: breath is far shorter.
MAX_TEMPLATE_CHARS = 500
MAX_TEMPLATE_TOKENS = 100

_TOKEN_RE = re.compile(r"\(([^()]*)\)|\{([A-Za-z_][A-Za-z0-9_]*)(?::([A-Za-z_]+))?\}|([^\s(){}]+)")
_WORD_RE = re.compile(r"^[a-z0-9']+$")


#: Courtesy words and phrases a request may carry anywhere; they never change what is asked.
COURTESY = ("could you please", "can you please", "would you please", "could you", "can you",
            "would you", "will you", "please", "kindly", "thank you", "thanks")
_COURTESY_RE = re.compile(r"(?:^| )(?:" + "|".join(re.escape(c) for c in COURTESY) + r")(?= |$)")


def normalise(text: str) -> str:
    """Lower case, punctuation dropped, single spaces: "Where is my pill-box?" ->
    "where is my pill box"."""
    text = text.lower().replace("'", "")
    return " ".join(re.findall(r"[a-z0-9]+", text))


def strip_courtesy(normalised: str) -> str:
    """A normalised utterance without its courtesy words: "could you bring me the cup
    please" -> "bring me the cup"."""
    return " ".join(_COURTESY_RE.sub(" ", f" {normalised} ").split())


@dataclass(frozen=True)
class Slot:
    param: str
    cls: str | None          # a SLOT_CLASSES key, or None: the words are the value


#: A compiled token: ("words", (w, ...)), ("group", ((w, ...), ...)) or ("slot", param).
Token = tuple[str, Any]


def match_tokens(tokens: tuple[Token, ...], words: list[str]) -> dict[str, str] | None:
    """The slots' words when ``words`` match ``tokens`` (None: they do not), chosen as a
    backtracking matcher would: a group's first fitting alternative, else none; a slot's
    fewest words. O(tokens x words x group words)."""
    T, n = len(tokens), len(words)
    if n == 0:
        return None     # nothing said matches nothing (even a template of optional words)
    # ok[i][j]: tokens[i:] can match words[j:]
    ok = [[False] * (n + 1) for _ in range(T + 1)]
    ok[T][n] = True

    def fits(seq: tuple[str, ...], j: int) -> bool:
        return j + len(seq) <= n and tuple(words[j:j + len(seq)]) == seq

    for i in range(T - 1, -1, -1):
        kind, val = tokens[i]
        nxt, row = ok[i + 1], ok[i]
        if kind == "slot":
            later = False
            for j in range(n - 1, -1, -1):
                later = later or nxt[j + 1]
                row[j] = later
        elif kind == "words":
            k = len(val)
            for j in range(n + 1 - k):
                row[j] = nxt[j + k] and fits(val, j)
        else:
            for j in range(n + 1):
                row[j] = nxt[j] or any(fits(alt, j) and nxt[j + len(alt)] for alt in val)
    if not ok[0][0]:
        return None
    out: dict[str, str] = {}
    j = 0
    for i, (kind, val) in enumerate(tokens):
        nxt = ok[i + 1]
        if kind == "words":
            j += len(val)
        elif kind == "group":
            j += next((len(alt) for alt in val if fits(alt, j) and nxt[j + len(alt)]), 0)
        else:
            k = next(k for k in range(j + 1, n + 1) if nxt[k])
            out[val] = " ".join(words[j:k])
            j = k
    return out


@dataclass
class Template:
    """One compiled utterance template of a mission. ``source`` is the regular expression
    the template stands for (its length ranks templates by how specific they are)."""
    mission: str
    text: str
    tokens: tuple[Token, ...]
    source: str
    slots: tuple[Slot, ...]
    params: dict[str, Any]
    file: str
    line: int

    def match(self, normalised: str) -> dict[str, str] | None:
        return match_tokens(self.tokens, normalised.split())

    def to_json(self) -> dict[str, Any]:
        return {"say": self.text, "slots": {s.param: s.cls or "value" for s in self.slots},
                "params": self.params}

    def example(self, world: Any = None) -> str:
        """The template as a person would say it: the first word of each group, each slot
        filled with a name from the map of its class (or the class's name): "bring me the
        blue cup"."""
        def fill(m: re.Match) -> str:
            group, slot, cls, word = m.groups()
            if group is not None:
                return group.split("|")[0].strip()
            if slot is not None:
                s = next(x for x in self.slots if x.param == slot)
                return example_words(world, s.cls) or (s.cls or s.param).replace("_", " ")
            return word
        return " ".join(w for w in (fill(m) for m in _TOKEN_RE.finditer(self.text)) if w)


def example_words(world: Any, cls: str | None) -> str:
    """A name from the map for a slot class (the first by id), or ""."""
    if world is None or cls is None:
        return ""
    kinds = SLOT_CLASSES.get(cls) or None
    nodes = sorted((n for n in world.nodes() if kinds is None or n.kind in kinds),
                   key=lambda n: n.id)
    for n in nodes:
        label = world.label(n.id)
        if label and label != n.id:
            return label
    return ""


def compile_template(text: str, mission: Mission, file: str, line: int,
                     params: dict[str, Any] | None = None) -> Template:
    """Compile ``text`` against ``mission``'s parameters; MissionError(file, line) if wrong."""
    def bad(msg: str) -> MissionError:
        return MissionError(f"utterance {text!r}: {msg}", file=file, line=line)

    params = dict(params or {})
    if len(text) > MAX_TEMPLATE_CHARS:
        raise MissionError(f"utterance {text[:40]!r}...: {len(text)} characters (at most "
                           f"{MAX_TEMPLATE_CHARS})", file=file, line=line)
    for name, value in params.items():
        spec = mission.parameters.get(name)
        if spec is None:
            raise bad(f"params: {name} is not a parameter of mission {mission.name}")
        try:
            spec.check(value)
        except MissionError as err:
            raise bad(f"params: {name}: {err.message}") from None
    regex = ["^ "]
    tokens: list[Token] = []
    slots: list[Slot] = []
    last_was_slot = False
    pos = 0
    for m in _TOKEN_RE.finditer(text):
        if text[pos:m.start()].strip():
            raise bad(f"cannot read {text[pos:m.start()].strip()!r}")
        pos = m.end()
        if len(tokens) == MAX_TEMPLATE_TOKENS:
            raise bad(f"more than {MAX_TEMPLATE_TOKENS} words, groups and slots")
        group, slot, cls, word = m.groups()
        if group is not None:
            alts = [normalise(a) for a in group.split("|")]
            if not all(alts):
                raise bad(f"empty alternative in ({group})")
            regex.append("(?:(?:" + "|".join(re.escape(a) + " " for a in alts) + "))?")
            tokens.append(("group", tuple(tuple(a.split()) for a in alts)))
            continue
        if slot is not None:
            if last_was_slot:
                raise bad("two slots need a word between them")
            spec = mission.parameters.get(slot)
            if spec is None:
                known = ", ".join(sorted(mission.parameters)) or "none"
                raise bad(f"{{{slot}}} is not a parameter of mission {mission.name} "
                          f"(known: {known})")
            if any(s.param == slot for s in slots) or slot in params:
                raise bad(f"{{{slot}}} is given twice")
            if cls is not None and cls not in SLOT_CLASSES:
                raise bad(f"unknown slot class {cls!r} (known: {', '.join(SLOT_CLASSES)})")
            if cls is None and spec.type == "node_id":
                cls = "node"
            slots.append(Slot(slot, cls))
            regex.append(f"(?P<{slot}>(?:[a-z0-9]+ )+?)")
            tokens.append(("slot", slot))
            last_was_slot = True
            continue
        w = normalise(word)
        if w:
            regex.append(re.escape(w) + " ")
            tokens.append(("words", tuple(w.split())))
            last_was_slot = False
    if text[pos:].strip():
        raise bad(f"cannot read {text[pos:].strip()!r}")
    if not slots and len(regex) == 1:
        raise bad("no words")
    regex.append("$")
    return Template(mission=mission.name, text=text, tokens=tuple(tokens),
                    source="".join(regex), slots=tuple(slots), params=params, file=file,
                    line=line)


@dataclass
class CatalogueEntry:
    """A mission that can be asked for: the loaded Mission, its file, its templates."""
    mission: Mission
    file: str
    templates: list[Template] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        m = self.mission
        return {
            # The file's name in its catalogue folder: the network never sees where the
            # server's files are (nor can it name one: missions are asked for by name).
            "name": m.name, "description": m.description, "file": Path(self.file).name,
            "parameters": [{"name": p.name, "type": p.type, "required": p.required and p.default is None,
                            "default": plain(p.default), "runtime": p.runtime,
                            "enum": plain(p.enum), "description": p.description}
                           for p in m.parameters.values()],
            "utterances": [t.to_json() for t in self.templates],
        }


def read_templates(mission: Mission, file: str) -> list[Template]:
    """The mission file's ``utterances`` compiled (MissionError with file:line)."""
    data = load_yaml(file)
    items = data.get("utterances") if isinstance(data, dict) else None
    if not items:
        return []
    out = []
    for i, item in enumerate(items):
        line = items.item_lines[i] if isinstance(items, LineList) else 0
        if isinstance(item, str):
            out.append(compile_template(item, mission, file, line))
        elif isinstance(item, dict) and isinstance(item.get("say"), str):
            line = getattr(item, "line", line) or line
            out.append(compile_template(item["say"], mission, file, line,
                                        plain(item.get("params") or {})))
        else:  # the schema check has already refused it; keep the message anyway
            raise MissionError("an utterance is a string or {say:, params:}", file=file, line=line)
    return out


def load_catalogue(paths: list[str | Path], load: Callable[[str], Mission]) -> tuple[
        dict[str, CatalogueEntry], list[str]]:
    """Mission files (files, or directories: their ``*.yaml``, not subtree libraries) ->
    (name -> entry, problems as one line each). ``load`` is ``Executive.load``."""
    files: list[Path] = []
    for p in paths:
        p = Path(p)
        files.extend(sorted(p.glob("*.yaml")) if p.is_dir() else [p])
    entries: dict[str, CatalogueEntry] = {}
    problems: list[str] = []
    for f in files:
        try:
            data = load_yaml(str(f))
            if isinstance(data, LineDict) and "tree" not in data:
                continue        # a library of subtrees: included, never asked for
            mission = load(str(f))
            entry = CatalogueEntry(mission, str(f), read_templates(mission, str(f)))
        except (MissionError, OSError) as err:
            problems.append(str(err).splitlines()[0])
            continue
        if mission.name in entries:
            problems.append(f"{f}: mission {mission.name} is also in {entries[mission.name].file}")
            continue
        entries[mission.name] = entry
    return entries, problems


class Vocabulary:
    """Missions from the catalogue, objects/places/rooms from the map; thread-safe.

    ``revision`` goes up on every map change; ``snapshot()`` rebuilds lazily."""

    def __init__(self, world: Any, catalogue: dict[str, CatalogueEntry],
                 on_change: Callable[[int], None] | None = None):
        self.world = world
        self.catalogue = catalogue
        self.revision = 1
        self._lock = threading.Lock()
        self._cache: dict[str, Any] | None = None
        self._on_change = on_change
        self._unsubscribe = None
        if world is not None and callable(getattr(world, "subscribe", None)):
            self._unsubscribe = world.subscribe(self._map_changed)

    def _map_changed(self, change: Any) -> None:
        # Called on whichever thread changed the map (often the tick thread): stay cheap.
        with self._lock:
            self.revision += 1
            self._cache = None
            rev = self.revision
        if self._on_change is not None:
            self._on_change(rev)

    def close(self) -> None:
        if self._unsubscribe is not None:
            self._unsubscribe()
            self._unsubscribe = None

    @property
    def templates(self) -> list[Template]:
        return [t for e in self.catalogue.values() for t in e.templates]

    def snapshot(self) -> dict[str, Any]:
        with self._lock:
            if self._cache is not None:
                return self._cache
            rev = self.revision
        snap = {"revision": rev,
                "missions": [e.to_json() for e in self.catalogue.values()],
                **self._map_words()}
        with self._lock:
            if self.revision == rev:
                self._cache = snap
        return snap

    def _map_words(self) -> dict[str, Any]:
        w = self.world
        if w is None:
            return {"objects": [], "places": [], "rooms": []}
        with w.lock:
            objects = []
            for o in w.small_objects():
                objects.append({"id": o.id, "label": w.label(o.id), "type": o.type,
                                "color": o.color or "", "description": o.description or "",
                                "room": w.room_of(o.id).id, "where": w.describe_location(o.id)})
            rooms = [{"id": r.id, "name": r.name or r.id} for r in w.rooms]
            places = []
            for o in w.large_objects():
                room = w.room_of(o.id)
                places.append({"id": o.id, "label": w.label(o.id), "type": o.type,
                               "room": room.id,
                               "name": f"{w.label(o.id)} in the {room.name or room.id}",
                               "kinds": list(SLOT_CLASSES_OF.get(o.kind, ()))})
        return {"objects": objects, "places": places, "rooms": rooms}


#: node kind -> slot classes that accept it (for the vocabulary listing)
SLOT_CLASSES_OF: dict[str, tuple[str, ...]] = {}
for _cls, _kinds in SLOT_CLASSES.items():
    for _k in _kinds:
        SLOT_CLASSES_OF.setdefault(_k, ())
        SLOT_CLASSES_OF[_k] += (_cls,)
