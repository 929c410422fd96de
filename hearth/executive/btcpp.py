"""Missions to and from BehaviorTree.CPP v4 XML (what Groot2 and Nav2 read and write).

``export_mission(path)`` writes a checked mission as BT.CPP v4 XML (``BTCPP_format="4"``):
one ``<BehaviorTree>`` for the mission and one per subtree it includes, ``{key}`` blackboard
remapping for inputs and outputs, and a ``<TreeNodesModel>`` with every skill's declared ports
(direction, type, default, description), the Hearth node types that BT.CPP has no equivalent
for (``ForEach``, ``Watch``, ``Guard``, ``Check``, ``StateMachine``/``State``, ``Succeed``,
``Fail``) and one ``<SubTree>`` model per tree carrying its parameters.

``import_tree(path)`` reads BT.CPP v4 XML back into a mission (YAML text) that is then
checked like any other mission. BT.CPP idioms with no Hearth node of their own are rewritten
into Hearth nodes (``LOWERED_PORTS``: Script and ScriptCondition for the script subset
Hearth's conditions carry, SetBlackboard, Precondition, Delay, Sleep, RunOnce, IfThenElse,
Switch2..6; the pre/post-condition attributes; ``_autoremap``). Every problem is a
:class:`~hearth.executive.errors.MissionError` with the XML file and line: a leaf that is no
registered skill, a port the skill does not declare (in the tree or in its Groot2 model), a
BT.CPP or Nav2 node Hearth does not map (each has its reason in ``REFUSED``), a script beyond
the subset, an XML entity or DTD, a syntax error.

``nodes_header()`` is the C++ header (hearth/executive/cpp/hearth_nodes.hpp) with Hearth's node
types for BT.CPP, which ``hearth export --nodes-header`` writes beside a mission.

The mapping is the table in docs/missions.md, "From and to BehaviorTree.CPP". Inside one
``<BehaviorTree>``, ``{name}`` is a port of that tree (a Hearth ``$parameter``) when the
tree's ``<SubTree>`` model declares it, and a blackboard key otherwise. Literals carry their
type through the port they feed: text as is, numbers and booleans as BT.CPP writes them,
lists, mappings and anything ambiguous as ``json:...`` (BT.CPP's JSON prefix).

``live_tree(mission)`` is the tree a running mission shows over the Groot2 protocol
(``hearth.executive.groot2``): the compiled tree with every include expanded, each node with its
``_uid``, as BT.CPP's ``WriteTreeToXML(tree, add_metadata=true)`` writes it.

The XML is read with lxml and never resolves entities, loads a DTD or touches the network
(as hearth/worldmodel/io.py reads world files); a file with a DOCTYPE is refused before parsing.

This module is the front door (the names below); the work is in its neighbours, bottom first:
btcpp_format.py (the node tables and literals through typed ports), btcpp_script.py (the
script subset), btcpp_export.py, btcpp_import.py and btcpp_live.py.
"""
from __future__ import annotations

from hearth.executive.btcpp_export import custom_model, export_mission, nodes_header, skill_model
from hearth.executive.btcpp_format import (
    CUSTOM, LOWERED_PORTS, REFUSED, decode_literal, encode_literal,
)
from hearth.executive.btcpp_import import import_tree, parse_xml
from hearth.executive.btcpp_live import LiveTree, live_tree
from hearth.executive.btcpp_script import script_assignments, script_condition

__all__ = ["CUSTOM", "LOWERED_PORTS", "REFUSED", "LiveTree", "custom_model", "decode_literal",
           "encode_literal", "export_mission", "import_tree", "live_tree", "nodes_header",
           "parse_xml", "script_assignments", "script_condition", "skill_model"]
