import re

import pytest
from hypothesis import given, settings, strategies as st

from hearth.cli.main import main
from hearth.executive.errors import MissionValidationError
from hearth.executive.missionfile import check_value, load_mission, parse_expression, validate_file
from hearth.executive.missionfile_types import parse_param_text
from hearth.executive.testing import test_skills
from hearth.executive.errors import MissionError


def errors(path):
    return [str(e) for e in validate_file(path, test_skills())]


def test_valid_mission_loads_with_paths_named_after_nodes(mission_file):
    path = mission_file("""
        name: demo
        parameters:
          where: {type: node_id, default: kitchen}
        tree:
          sequence:
            - skill: Navigate
              inputs: {target: $where}
              outputs: {reached: at}
            - skill: Speak
              inputs: {text: "{at}"}
    """)
    m = load_mission(path, test_skills())
    assert [n.path for n in m.nodes()] == ["/demo", "/demo/Navigate", "/demo/Speak"]


def test_yaml_syntax_error_is_one_line_with_file_and_line(mission_file):
    path = mission_file("name: x\ntree:\n  sequence: [\n")
    (err,) = errors(path)
    assert err.startswith(f"{path}:") and "YAML syntax error" in err


def test_unknown_node_kind_is_reported_at_its_line(mission_file):
    path = mission_file("""
        name: x
        tree:
          sequence:
            - skill: Act
            - dance: {}
    """)
    assert errors(path) == [f"{path}:6: unknown node kind 'dance' (known: sequence, selector, "
                            "parallel, retry, timeout, repeat, inverter, force_success, "
                            "force_failure, for_each, guard, watch, skill, condition, succeed, "
                            "fail, include, state_machine)"]


def test_unknown_skill_missing_input_unknown_input_are_errors(mission_file):
    path = mission_file("""
        name: x
        tree:
          sequence:
            - skill: Teleport
            - skill: Navigate
            - skill: Speak
              inputs: {text: hi, volume: 3}
    """)
    errs = errors(path)
    assert f"{path}:5: unknown skill 'Teleport'" in errs
    assert f"{path}:6: skill Navigate: missing required input 'target' (node_id|pose)" in errs
    assert any(e.startswith(f"{path}:8: skill Speak has no input 'volume'") for e in errs)


def test_reading_a_key_nothing_writes_is_an_error(mission_file):
    path = mission_file("""
        name: x
        tree:
          skill: Speak
          inputs: {text: "{greeting}"}
    """)
    assert errors(path) == [f"{path}:5: reads key {{greeting}} that nothing writes"]


def test_type_mismatch_between_writer_and_reader(mission_file):
    path = mission_file("""
        name: x
        tree:
          sequence:
            - skill: Detect
              inputs: {object: cup}
              outputs: {found: flag}
            - skill: Speak
              inputs: {text: "{flag}"}
    """)
    (err,) = errors(path)
    assert err.startswith(f"{path}:9: key {{flag}} holds boolean") and "string is expected" in err


def test_literal_and_parameter_type_mismatch(mission_file):
    path = mission_file("""
        name: x
        parameters:
          n: {type: number, default: 1.5}
        tree:
          sequence:
            - skill: Speak
              inputs: {text: $n}
            - skill: Navigate
              inputs: {target: 42}
    """)
    errs = errors(path)
    assert f"{path}:8: input text of Speak: parameter $n is number, string expected" in errs
    assert f"{path}:10: input target of Navigate: expected node_id|pose, got 42" in errs


def test_cyclic_include_is_an_error(mission_file):
    mission_file("""
        name: b
        tree:
          include: a.yaml
    """, "b.yaml")
    path = mission_file("""
        name: a
        tree:
          include: b.yaml
    """, "a.yaml")
    errs = errors(path)
    assert len(errs) == 1 and "cyclic include" in errs[0] and errs[0].startswith(f"{path}:4:") \
        or any("cyclic include" in e for e in errs)


def test_subtree_include_remaps_parameters_and_scopes_keys(mission_file):
    path = mission_file("""
        name: x
        tree:
          sequence:
            - include: visit
              params: {place: kitchen}
            - include: visit
              params: {place: hall}
        subtrees:
          visit:
            parameters: {place: {type: node_id}}
            tree:
              sequence:
                - skill: Navigate
                  inputs: {target: $place}
                  outputs: {reached: here}
                - skill: Speak
                  inputs: {text: "{here}"}
    """)
    m = load_mission(path, test_skills())
    navs = [n for n in m.nodes() if n.skill_name == "Navigate"]
    assert [n.inputs["target"].value for n in navs] == ["kitchen", "hall"]
    assert navs[0].outputs["reached"].key != navs[1].outputs["reached"].key


def test_state_machine_unmapped_outcome_and_unknown_target(mission_file):
    path = mission_file("""
        name: x
        tree:
          state_machine:
            initial: go
            states:
              go:
                do: {skill: Act}
                transitions: {success: talk}
            outcomes: {done: success}
    """)
    errs = errors(path)
    assert any("outcome 'failure' has no transition" in e for e in errs)
    assert any("unknown state or outcome 'talk'" in e for e in errs)


def test_cli_validate_exits_2_with_one_line(mission_file, capsys):
    path = mission_file("name: x\ntree: {skill: NoSuchSkill}\n")
    assert main(["validate", path]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"{path}:2: unknown skill 'NoSuchSkill'"]


def test_cli_wrong_parameter_type_exits_2(mission_file, capsys, tmp_path):
    case = tmp_path / "case.yaml"
    case.write_text("params: {}\n")
    assert main(["step", "missions/go_to_rest.yaml", "--param", "nonsense=1", "--ticks", "1"]) == 2
    assert "parameter nonsense" in capsys.readouterr().err


def test_parse_param_text_types():
    assert parse_param_text("n", "number", "2") == 2.0
    assert parse_param_text("p", "pose", "[1, 2, 0.5]") == [1, 2, 0.5]
    assert parse_param_text("s", "string", "007") == "007"
    with pytest.raises(MissionError, match="parameter b: expected boolean"):
        parse_param_text("b", "boolean", "maybe")


def test_conditions_are_parsed_not_evaluated_as_python():
    e = parse_expression("{battery} >= 0.2")
    assert e.op == ">=" and e.right.value == 0.2
    with pytest.raises(ValueError):
        parse_expression("__import__('os').system('true')")


def test_go_to_rest_validates_against_the_real_registry():
    assert validate_file("missions/go_to_rest.yaml") == []


@settings(max_examples=60, deadline=None)
@given(st.one_of(st.integers(), st.floats(allow_nan=False), st.text(max_size=5), st.booleans(),
                 st.lists(st.integers(), max_size=6), st.none()))
def test_check_value_number_never_accepts_booleans_or_strings(value):
    if check_value("number", value):
        assert isinstance(value, (int, float)) and not isinstance(value, bool)


@pytest.mark.parametrize("text,expected", [
    ("name: x\ntree: [\n", ":3: YAML syntax error"),
    ("name: x\ntree:\n  juggle: {}\n", ":3: unknown node kind 'juggle'"),
    ("name: x\ntree:\n  skill: Juggle\n", ":3: unknown skill 'Juggle'"),
])
def test_cli_show_bad_missions_exit_2_with_one_line(mission_file, capsys, text, expected):
    path = mission_file(text)
    assert main(["show", path]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(path) and expected in err[0]


def test_cli_wrong_parameter_type_is_one_line_naming_the_parameter(mission_file, capsys):
    path = mission_file("name: x\nparameters:\n  n: {type: number}\ntree: {succeed: ok}\n")
    assert main(["run", path, "--param", "n=lots"]) == 2
    assert capsys.readouterr().err.strip() == "parameter n: expected number, got 'lots'"
    assert main(["run", "missions/go_to_rest.yaml", "--param", "presence=maybe"]) == 2
    assert "parameter presence: expected one of ['home', 'away']" in capsys.readouterr().err


def test_hearth_show_draws_ascii_and_dot(capsys):
    assert main(["show", "missions/go_to_rest.yaml"]) == 0
    out = capsys.readouterr().out
    assert "NavigateTo drive_near_user(target={near_target})" in out
    assert main(["show", "missions/go_to_rest.yaml", "--format", "dot"]) == 0
    assert capsys.readouterr().out.startswith('digraph "go_to_rest"')


def test_a_library_of_subtrees_validates_and_is_included_from_another_file(mission_file):
    lib = mission_file("""
        name: shared
        subtrees:
          visit:
            parameters: {place: {type: node_id}}
            tree: {skill: Navigate, inputs: {target: $place}}
          broken:
            tree: {skill: Speak, inputs: {text: "{nothing}"}}
    """, "shared.yaml")
    errs = errors(lib)
    assert errs == [f"{lib}:8: reads key {{nothing}} that nothing writes"]
    path = mission_file("""
        name: user
        tree:
          include: shared.yaml#visit
          params: {place: hall}
    """)
    m = load_mission(path, test_skills())
    assert [n.path for n in m.nodes()] == ["/user", "/user/Navigate"]
    clean = mission_file("name: lib\nsubtrees:\n  s: {tree: {succeed: ok}}\n", "lib.yaml")
    assert errors(clean) == []
    with pytest.raises(MissionValidationError, match="subtrees but no tree"):
        load_mission(clean, test_skills())


@settings(max_examples=30, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(["Act", "Speak"]), st.integers(0, 2),
                          st.booleans()), min_size=1, max_size=8))
def test_every_node_reports_the_line_its_mapping_starts_on(tmp_path_factory, leaves):
    lines = ["name: x", "tree:", "  sequence:"]
    expected = []
    for skill, blanks, comment in leaves:
        lines += [""] * blanks + (["    # a comment"] if comment else [])
        lines.append(f"    - skill: {skill}")
        expected.append(len(lines))
        if skill == "Speak":
            lines.append("      inputs: {text: hello}")
    path = tmp_path_factory.mktemp("lines") / "m.yaml"
    path.write_text("\n".join(lines) + "\n")
    m = load_mission(str(path), test_skills())
    assert [n.line for n in m.root.children] == expected


# -- hostile and careless files (issue 19) ---------------------------------------------------

BOMB = "\n".join(["  a: &a [lol, lol, lol, lol, lol, lol, lol, lol, lol]"]
                 + [f"  {c}: &{c} [{', '.join(['*' + p] * 9)}]"
                    for p, c in zip("abcdefgh", "bcdefghi")])


@pytest.mark.parametrize("where", ["blackboard", "default", "input"])
def test_an_alias_bomb_is_refused_at_load_in_one_line(mission_file, where):
    body = {"blackboard": f"blackboard:\n{BOMB}\ntree: {{succeed: ok}}\n",
            "default": "parameters:\n  p:\n    type: any\n    default:\n"
                       + "\n".join("    " + l for l in BOMB.splitlines()) + "\ntree: {succeed: ok}\n",
            "input": "tree:\n  skill: Speak\n  inputs:\n    text:\n"
                     + "\n".join("    " + l for l in BOMB.splitlines()) + "\n"}[where]
    path = mission_file("name: bomb\n" + body)
    (err,) = errors(path)
    assert re.fullmatch(rf"{re.escape(path)}:\d+: YAML aliases expand this to more than "
                        r"250000 values", err)


def test_a_few_aliases_are_fine_and_a_self_reference_is_not(mission_file):
    path = mission_file("name: x\nblackboard:\n  a: &a [1, 2]\n  b: [*a, *a]\n"
                        "tree: {succeed: ok}\n")
    assert load_mission(path, test_skills()).blackboard["b"] == [[1, 2], [1, 2]]
    path = mission_file("name: x\nblackboard: {a: &a [*a]}\ntree: {succeed: ok}\n", "self.yaml")
    assert errors(path) == [f"{path}:2: a YAML alias refers to the value it is in"]


def test_deep_trees_are_refused_with_a_clear_line(mission_file):
    path = mission_file("name: deep\ntree: " + "{inverter: " * 3000 + "{succeed: ok}"
                        + "}" * 3000 + "\n")
    assert errors(path) == [f"{path}:2: YAML nests more than 150 levels deep"]
    nested = "".join("  " * i + "inverter:\n" for i in range(1, 70)) + "  " * 70 + "succeed: ok\n"
    path = mission_file("name: deep\ntree:\n" + nested, "d2.yaml")
    (err,) = errors(path)
    assert err.startswith(f"{path}:") and err.endswith("the tree is more than 64 nodes deep")


def test_an_include_bomb_stops_at_the_tree_size_limit(mission_file):
    subtrees = "".join(f"  s{i}:\n    tree:\n      sequence: [{{include: s{i + 1}}}, "
                       f"{{include: s{i + 1}}}]\n" for i in range(20))
    path = mission_file("name: x\ntree: {include: s0}\nsubtrees:\n" + subtrees
                        + "  s20: {tree: {succeed: ok}}\n")
    (err,) = errors(path)
    assert "the tree has more than 20000 nodes" in err


def test_siblings_are_named_uniquely_and_in_order(mission_file):
    path = mission_file("""
        name: x
        tree:
          sequence:
            - succeed: a
            - {succeed: b, name: succeed_3}
            - succeed: c
            - succeed: d
            - {succeed: e, name: succeed_2}
            - succeed: f
    """)
    names = [n.name for n in load_mission(path, test_skills()).root.children]
    assert names == ["succeed", "succeed_3", "succeed_2", "succeed_4", "succeed_2_2", "succeed_5"]


@pytest.mark.parametrize("attr, value, message", [
    ("retry", "times: 100000000000000000000000000",
     "integer '100000000000000000000000000' is too large (at most 2^63 - 1)"),
    ("retry", "times: 1001", "times: 1001 is greater than the maximum of 1000"),
    ("timeout", "seconds: .nan", "'.nan' is not a finite number"),
    ("timeout", "seconds: .inf", "'.inf' is not a finite number"),
    ("timeout", "seconds: 86401", "seconds: 86401 is greater than the maximum of 86400"),
    ("repeat", "times: 1000001", "times: 1000001 is greater than the maximum of 1000000"),
])
def test_retry_counts_and_timeouts_are_finite_and_bounded(mission_file, attr, value, message):
    path = mission_file(f"name: x\ntree:\n  {attr}: {{succeed: ok}}\n  {value}\n")
    assert errors(path) == [f"{path}:4: {message}"]


@pytest.mark.parametrize("text, message", [
    ("blackboard: {n: 1.0e+400}", "'1.0e+400' is not a finite number"),
    ("blackboard: {d: 2001-12-14}", "date and time values are not allowed"),
    ("blackboard: {n: " + "9" * 5000 + "}", "is too large"),
    ("blackboard: {o: !!python/object/apply:os.system [true]}", "could not determine a constructor"),
])
def test_only_finite_plain_data_is_read(mission_file, text, message):
    path = mission_file(f"name: x\n{text}\ntree: {{succeed: ok}}\n")
    (err,) = errors(path)
    assert err.startswith(f"{path}:2: ") and message in err


def test_nan_parameters_and_condition_literals_are_refused(mission_file):
    with pytest.raises(MissionError, match="cannot read '.nan' as number: '.nan' is not a finite"):
        parse_param_text("speed", "number", ".nan")
    with pytest.raises(MissionError, match="not a finite number"):
        parse_param_text("pose", "pose", "{x: .inf, y: 0}")
    path = mission_file("name: x\nblackboard: {v: 1}\ntree: {condition: '{v} < .nan'}\n")
    (err,) = errors(path)
    assert err.startswith(f"{path}:3: cannot read a value in condition")
    assert not check_value("number", float("nan")) and not check_value("integer", 2**64)


@pytest.mark.parametrize("target", ["/etc/passwd#x", "../../../../../proc/self/environ#x",
                                    "/dev/zero#x", "outside/../../x.yaml"])
def test_includes_stay_inside_the_missions_folder(mission_file, target):
    path = mission_file(f"name: x\ntree:\n  include: '{target}'\n")
    (err,) = errors(path)
    assert err.startswith(f"{path}:3: include ") and "outside the mission's folder" in err


def test_an_include_through_a_symlink_out_of_the_folder_is_refused(mission_file, tmp_path):
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "elsewhere" / "s.yaml").write_text("name: s\ntree: {succeed: ok}\n")
    (tmp_path / "here").mkdir()
    (tmp_path / "here" / "link.yaml").symlink_to(tmp_path / "elsewhere" / "s.yaml")
    path = mission_file("name: x\ntree: {include: link.yaml}\n", "here/m.yaml")
    (err,) = errors(path)
    assert "outside the mission's folder" in err


def test_a_mission_path_that_is_no_regular_file_is_refused(tmp_path):
    import os
    os.mkfifo(tmp_path / "m.yaml")
    for path in (tmp_path / "m.yaml", tmp_path):
        (err,) = errors(str(path))
        assert "not a regular file" in str(err)


def test_validating_is_linear_in_the_number_of_siblings(mission_file):
    """10,000 same-named siblings: every name is unique and counted once (the old loop tried
    _2, _3, ... afresh for each, which took 57 s; timings are in `hearth bench fuzz`)."""
    path = mission_file("name: wide\ntree:\n  sequence:\n" + "    - succeed: ok\n" * 10_000)
    names = [n.name for n in load_mission(path, test_skills()).root.children]
    assert names[:3] == ["succeed", "succeed_2", "succeed_3"] and names[-1] == "succeed_10000"
    assert len(set(names)) == 10_000


def test_the_schemas_maxima_are_the_documented_limits():
    from hearth.executive import missionfile_format as fmt
    from hearth.executive.missionfile import schema
    defs = schema()["$defs"]
    assert defs["retry"]["properties"]["times"]["maximum"] == fmt.MAX_RETRY_TIMES
    assert defs["repeat"]["properties"]["times"]["maximum"] == fmt.MAX_REPEAT_TIMES
    assert defs["timeout"]["properties"]["seconds"]["maximum"] == fmt.MAX_TIMEOUT_SECONDS
    assert defs["parallel"]["properties"]["threshold"]["maximum"] == fmt.MAX_TREE_NODES


def test_a_malformed_enum_in_an_included_subtree_is_one_line(mission_file):
    path = mission_file("""
        name: x
        tree: {include: s, params: {p: 1}}
        subtrees:
          s:
            parameters: {p: {type: integer, enum: 3, default: 1, items: 7}}
            tree: {succeed: ok}
    """)
    errs = errors(path)
    assert errs and all(e.startswith(f"{path}:6: ") for e in errs), errs


def test_a_huge_wrong_value_is_reported_in_a_short_line(mission_file):
    path = mission_file("name: x\ntree:\n  skill: Navigate\n  inputs: {target: [" + "1, " * 3000
                        + "1]}\n")
    (err,) = errors(path)
    assert err.startswith(f"{path}:4: input target of Navigate: expected node_id|pose, got [1, ")
    assert len(err) < 300 + len(path)


# -- issue 44 ----------------------------------------------------------------------------------

def test_an_include_path_with_a_nul_byte_is_one_line(mission_file, capsys):
    path = mission_file('name: x\ntree:\n  include: "sub\\0.yaml#x"\n')
    (err,) = errors(path)
    assert err.startswith(f"{path}:3: include ") and "holds a NUL byte" in err
    assert main(["validate", path]) == 2
    assert "Traceback" not in capsys.readouterr().err


def test_a_mission_name_too_long_for_a_file_name_is_refused_at_validate(mission_file, capsys):
    path = mission_file(f"name: {'m' * 300}\ntree: {{succeed: ok}}\n")
    assert main(["validate", path]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.startswith(f"{path}:1: ") and "is too long" in line


@pytest.mark.parametrize("text", ["0x10", "010", "1_000", "1:30", "0b11", "16\x01"])
def test_an_integer_parameter_is_written_in_decimal(text):
    with pytest.raises(MissionError, match="parameter max_places: "):
        parse_param_text("max_places", "integer", text)
    assert parse_param_text("max_places", "integer", "16") == 16
    assert parse_param_text("r", "number", "1e3") == 1000.0


def test_a_parameter_with_a_control_character_is_refused_not_resolved(capsys):
    assert main(["run", "missions/go_to_rest.yaml", "--param", "presence=home\x01"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == "parameter presence: 'home\\x01' holds the control character U+0001"
    with pytest.raises(MissionError, match="control character U[+]0001"):
        parse_param_text("user_room", "node_id", "kitchen\x01")


def test_a_parameter_given_twice_is_refused_not_the_last_taken(capsys):
    assert main(["run", "missions/go_to_rest.yaml", "--param", "presence=home",
                 "--param", "presence=away"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == "parameter presence: given twice (--param presence=...); give it once"
