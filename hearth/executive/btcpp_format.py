"""BehaviorTree.CPP v4 as Hearth reads and writes it: the node tables (BT.CPP's built-in nodes
and their ports, the idioms lowered into Hearth nodes, the nodes refused with their reasons,
Hearth's own node types) and literals through typed ports (``encode_literal``,
``decode_literal``). The mapping is the table in docs/missions.md, "From and to
BehaviorTree.CPP"."""
from __future__ import annotations

import json
import re
from typing import Any

import yaml

from hearth.executive.missionfile import plain
from hearth.executive.missionfile_format import IDENT


_KEY = re.compile(r"^\{(" + IDENT + r")\}$")
_PARAM = re.compile(r"^\$(" + IDENT + r")$")
#: Mission parameter keys carried on a SubTree model's ports as JSON attributes.
_CHECKS = ("minimum", "maximum", "kinds", "having", "sentinels", "pick_only")
_IDENT = re.compile(r"^" + IDENT + r"$")
# Operands of a condition, skipping quoted literals: {key} and $param are rewritten.
_EXPR_TOKEN = re.compile(r"'[^']*'|\"[^\"]*\"|\{(" + IDENT + r")\}|\$(" + IDENT + r")")

#: Hearth kind -> BT.CPP node (memory / reactive variants for sequence and selector).
SEQUENCE = {False: "Sequence", True: "ReactiveSequence"}
SELECTOR = {False: "Fallback", True: "ReactiveFallback"}
DECORATOR_TAGS = {"retry": "RetryUntilSuccessful", "timeout": "Timeout", "inverter": "Inverter",
                  "force_success": "ForceSuccess", "force_failure": "ForceFailure"}
#: BT.CPP nodes that import maps, with the ports each takes.
BUILTIN_PORTS: dict[str, tuple[str, ...]] = {
    "Sequence": (), "ReactiveSequence": (), "SequenceWithMemory": (),
    "Fallback": (), "ReactiveFallback": (),
    "Parallel": ("success_count", "failure_count"),
    "Inverter": (), "ForceSuccess": (), "ForceFailure": (),
    "RetryUntilSuccessful": ("num_attempts",), "Repeat": ("num_cycles",),
    "Timeout": ("msec",), "KeepRunningUntilFailure": (),
    "AlwaysSuccess": (), "AlwaysFailure": (),
}
BUILTIN_CONTROLS = {"Sequence", "ReactiveSequence", "SequenceWithMemory", "Fallback",
                    "ReactiveFallback", "Parallel"}

#: Hearth node types with no BT.CPP equivalent: (model element, ports).
#: A port is (direction, name, type, default, description).
CUSTOM: dict[str, tuple[str, tuple[tuple[str, str, str, str | None, str], ...]]] = {
    "ForEach": ("Decorator", (
        ("input_port", "in", "list", None, "the items: a {key}, a tree port or a json: list"),
        ("output_port", "as", "any", None, "the key each item is written to"),
        ("input_port", "until", "string", "failure",
         "failure: every item must succeed; success: stop at the first that succeeds"))),
    "Watch": ("Decorator", (
        ("input_port", "params", "string", None,
         "runtime parameters (;-separated): when one changes the child is halted and restarted"),)),
    "Guard": ("Decorator", (
        ("input_port", "while", "string", None,
         "a Hearth condition checked every tick; the child is halted and the guard fails "
         "when it stops holding"),)),
    "Check": ("Condition", (
        ("input_port", "expr", "string", None,
         "a Hearth condition: {key}, not {key}, or {key} OP value (== != < <= > >= in, not in)"),)),
    "StateMachine": ("Control", (
        ("input_port", "initial", "string", None, "the first state"),
        ("input_port", "outcomes", "string", None,
         "container outcome:status pairs (;-separated), status success or failure"))),
    "State": ("Decorator", (
        ("input_port", "transitions", "string", None,
         "outcome:target pairs (;-separated); a target is a state or a container outcome"),
        ("input_port", "outcome", "string", None,
         "after a success, the outcome is this key's value ({key})"))),
    "Succeed": ("Action", (("input_port", "message", "string", None, "feedback message"),)),
    "Fail": ("Action", (("input_port", "message", "string", None, "feedback message"),)),
}

#: Nodes import refuses, each with the reason (docs/missions.md has the same table).
REFUSED: dict[str, str] = {
    # Nav2 (nav2_behavior_tree)
    "RecoveryNode": "Nav2's RecoveryNode (retry the first child after the second recovers) has "
                    "no exact Hearth equivalent; write retry: {times: N} over a selector",
    "PipelineSequence": "Nav2's PipelineSequence (re-ticks every earlier child while a later "
                        "one runs) is not supported; use a reactive sequence",
    "RoundRobin": "Nav2's RoundRobin is not supported",
    "RateController": "Nav2's RateController (ticks its child at a rate) is not supported: "
                      "Hearth ticks the whole tree at the executive's rate",
    "DistanceController": "Nav2's DistanceController needs the robot's odometry in the tree; "
                          "not supported",
    "SpeedController": "Nav2's SpeedController is not supported",
    "GoalUpdater": "Nav2's GoalUpdater is not supported",
    "SingleTrigger": "Nav2's SingleTrigger is not supported",
    "PathLongerOnApproach": "Nav2's PathLongerOnApproach is not supported",
    # BehaviorTree.CPP built-ins without a Hearth mapping
    "WhileDoElse": "WhileDoElse is not supported; write a guard or a reactive selector",
    "ManualSelector": "ManualSelector is not supported",
    "TryCatch": "TryCatch is not supported; write a selector",
    "ParallelAll": "ParallelAll is not supported; use Parallel",
    "AsyncSequence": "AsyncSequence is not supported; use Sequence",
    "UnsetBlackboard": "UnsetBlackboard is not supported",
    "LoopInt": "Loop nodes are not supported; use ForEach (for_each)",
    "LoopDouble": "Loop nodes are not supported; use ForEach (for_each)",
    "LoopString": "Loop nodes are not supported; use ForEach (for_each)",
    "LoopBool": "Loop nodes are not supported; use ForEach (for_each)",
    "EntryUpdated": "EntryUpdated is not supported",
    "SkipUnlessUpdated": "SkipUnlessUpdated is not supported",
    "WaitValueUpdate": "WaitValueUpdate is not supported",
    "WasEntryUpdated": "WasEntryUpdated is not supported",
    "SubTreePlus": "SubTreePlus is BT.CPP v3; write <SubTree> with port remapping (v4)",
}
#: BT.CPP pre/post-condition attributes (scripts), in the order BT.CPP checks them.
PRE_ATTRS = ("_failureIf", "_successIf", "_skipIf", "_while")
POST_ATTRS = ("_onSuccess", "_onFailure", "_post", "_onHalted")
SCRIPT_ATTRS = PRE_ATTRS + POST_ATTRS
#: BT.CPP nodes import rewrites into Hearth nodes (docs/missions.md, "The mapping"), with
#: their ports.
LOWERED_PORTS: dict[str, tuple[str, ...]] = {
    "Script": ("code",), "ScriptCondition": ("code",), "SetBlackboard": ("value", "output_key"),
    "Precondition": ("if", "else"), "Delay": ("delay_msec",), "Sleep": ("msec",),
    "RunOnce": ("then_skip",), "IfThenElse": (),
    **{f"Switch{n}": ("variable",) + tuple(f"case_{i}" for i in range(1, n + 1))
       for n in range(2, 7)},
}
#: Parents under which BT.CPP's SKIPPED has a Hearth reading: a sequence passes over a
#: skipped child as over a success, a fallback as over a failure.
SKIP_AS = {"Sequence": "success", "ReactiveSequence": "success", "SequenceWithMemory": "success",
           "Fallback": "failure", "ReactiveFallback": "failure"}
#: Attributes that never are ports: Groot2's metadata and Hearth's comment.
META_ATTRS = ("_uid", "_fullpath", "_description")

BT_NAMES = set(BUILTIN_PORTS) | set(REFUSED) | set(LOWERED_PORTS) | {"SubTree", "Action", "Condition", "Control",
                                                "Decorator", "BehaviorTree", "root"}


# ---------------------------------------------------------------------------------------
# Literals through typed ports
# ---------------------------------------------------------------------------------------
def _alts(type_name: str) -> set[str]:
    return {t.strip() for t in str(type_name).split("|")}


def _textual(type_name: str) -> bool:
    return bool(_alts(type_name) & {"string", "node_id", "any"})


def _pointer_like(text: str) -> bool:
    # BT.CPP takes any value that starts with { and ends with } for a blackboard pointer.
    return len(text) >= 3 and text.startswith("{") and text.endswith("}")


def encode_literal(value: Any, type_name: str = "any") -> str:
    """A Hearth literal as the text of a BT.CPP port of Hearth type ``type_name``."""
    if isinstance(value, str):
        if _textual(type_name) and not _pointer_like(value) and not value.startswith("json:"):
            return value
        return "json:" + json.dumps(value, ensure_ascii=False)
    if isinstance(value, (bool, int, float)) and not _textual(type_name):
        return json.dumps(value)
    return "json:" + json.dumps(value, ensure_ascii=False)


def decode_literal(text: str, type_name: str = "any") -> Any:
    """The inverse of :func:`encode_literal`, lenient with BT.CPP's own spellings
    (``True``, ``1;2;3`` for a list). ValueError when the text cannot be read."""
    if text.startswith("json:"):
        try:
            return json.loads(text[5:])
        except json.JSONDecodeError as err:
            raise ValueError(f"cannot read {text!r} as JSON: {err.msg}") from None
    if _textual(type_name):
        return text
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        pass
    if "list" in _alts(type_name) and ";" in text:
        return [t for t in text.split(";")]
    try:
        return plain(yaml.safe_load(text))
    except yaml.YAMLError:
        raise ValueError(f"cannot read {text!r} as {type_name}") from None
