"""What a mission file may hold: its format version, the node kinds, identifiers, and the limits
on its size and depth (docs/missions.md, "Limits")."""
from __future__ import annotations

import re


FORMAT_VERSION = 1

#: Node kinds a mission file may use, with the attribute holding the child/children.
COMPOSITES = ("sequence", "selector", "parallel")
DECORATORS = ("retry", "timeout", "repeat", "inverter", "force_success", "force_failure",
              "for_each", "guard", "watch")
LEAVES = ("skill", "condition", "succeed", "fail")
KINDS = COMPOSITES + DECORATORS + LEAVES + ("include", "state_machine")
COMMON_ATTRS = ("name", "comment")

IDENT = r"[A-Za-z_][A-Za-z0-9_]*"
_KEY_RE = re.compile(r"^\{(" + IDENT + r")\}$")
_PARAM_RE = re.compile(r"^\$(" + IDENT + r")$")
_IDENT_RE = re.compile(r"^" + IDENT + r"$")

# Limits (docs/missions.md, "Limits").
#: Longest mission file, in characters.
MAX_FILE_CHARS = 1_000_000
#: Deepest YAML nesting (mappings and lists, counted through aliases).
MAX_YAML_DEPTH = 150
#: Most YAML values a file may stand for, counting what its aliases repeat (an 880-byte
#: alias bomb stands for hundreds of millions).
MAX_YAML_VALUES = 250_000
#: Most nodes in a compiled tree (includes counted each time they are included).
MAX_TREE_NODES = 20_000
#: Deepest compiled tree (the root is at depth 1).
MAX_TREE_DEPTH = 64
#: Largest ``retry: times``, ``repeat: times`` and ``timeout: seconds`` (also in the schema).
MAX_RETRY_TIMES = 1_000
MAX_REPEAT_TIMES = 1_000_000
MAX_TIMEOUT_SECONDS = 86_400
#: Integers a mission value may hold (what a 64-bit integer holds).
MAX_INT = 2**63 - 1
