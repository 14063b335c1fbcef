#!/usr/bin/env python3
"""Validates every JSON file in examples/, parts/ and datasets/ against its
JSON Schema in docs/schemas/ (docs/formats.md describes the formats).

Usage: validate_schemas.py [REPOSITORY_ROOT]

Which schema a file must satisfy is decided by the explicit table RULES below
(folder and file-name pattern, first match wins). A file that matches no rule
is a failure, so a new kind of file cannot slip through unvalidated: add a
rule (and a schema) for it. Every violation is printed with the file and the
JSON pointer of the offending value.

The script also checks that each schema is a valid draft 2020-12 schema,
that a few deliberately broken documents (a misspelled key, a wrong type, a
key that does not belong, ...) are rejected, so the test can fail, and that
documents using optional keys no shipped file uses (tolerances) are accepted.

Prints "N passed, M failed" last; exits 1 if anything failed. Needs the
Python package jsonschema (Debian: python3-jsonschema, 4.10 or later).
"""

import copy
import fnmatch
import json
import pathlib
import re
import sys

try:
    import jsonschema
except ImportError:
    print("validate_schemas.py: the Python package 'jsonschema' is missing "
          "(Debian: apt-get install python3-jsonschema)", file=sys.stderr)
    sys.exit(2)

# (folder relative to the root, file-name pattern, schema name). First match
# wins; files in sub-folders match nothing.
RULES = [
    ("examples", "machine_*.json", "machine"),
    ("examples", "*_pose.json", "pose"),
    ("examples", "aluminium_*.json", "material"),
    ("examples", "material_*.json", "material"),
    ("examples", "*_job.json", "job"),
    ("examples", "view_plan_*.json", "view_plan"),
    ("examples", "*_plan.json", "plan"),
    ("examples", "calibrate_wedge*.json", "calibrate_wedge"),
    ("examples", "characterize_*.json", "characterize"),
    ("examples", "detector_*.json", "detector"),
    ("examples", "bad_pixels_*.json", "bad_pixels"),
    ("examples", "calibrate_*.json", "calibrate_part"),
    ("examples", "study_*.json", "study"),
    ("examples", "bracket_extruded.json", "part_model"),
    ("examples/step", "*_lab.json", "recipe"),
    ("examples/step", "measure_*.json", "job"),
    ("examples/step", "verify_*.json", "verify"),
    ("examples/step", "*.json", "part_model"),
    ("examples/screw", "study_*.json", "study"),
    ("examples/screw", "*.json", "part_model"),
    ("examples", "stl_with_hole.json", "part_model"),
    ("parts", "*.json", "part_model"),
    ("datasets", "*.json", "recipe"),
    ("tests/data/htc2022", "machine.json", "machine"),
    ("tests/data/htc2022", "job.json", "job"),
    ("tests/data/htc2022", "disc.json", "part_model"),
    ("tests/data/htc2022", "material.json", "material"),
    ("tests/data/htc2022", "curve_recipe.json", "recipe"),
]
FOLDERS = ["examples", "examples/step", "examples/screw", "parts", "datasets", "tests/data/htc2022"]
SCHEMA_DIR = pathlib.Path("docs") / "schemas"


def schema_for(relative):
    """The schema name for a path relative to the root, or None."""
    relative = pathlib.PurePosixPath(relative)
    for folder, pattern, schema in RULES:
        if str(relative.parent) == folder and fnmatch.fnmatchcase(relative.name, pattern):
            return schema
    return None


def strip_comments(text):
    """Removes // and /* */ comments outside strings (xgauge accepts them)."""
    out, i, n = [], 0, len(text)
    while i < n:
        c = text[i]
        if c == '"':
            m = re.compile(r'"(?:[^"\\]|\\.)*"', re.S).match(text, i)
            end = m.end() if m else n
            out.append(text[i:end])
            i = end
        elif text.startswith("//", i):
            j = text.find("\n", i)
            i = n if j < 0 else j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            i = n if j < 0 else j + 2
        else:
            out.append(c)
            i += 1
    return "".join(out)


def load_json(path):
    return json.loads(strip_comments(path.read_text(encoding="utf-8")))


def load_schemas(root):
    """{file name: schema} of every docs/schemas/*.schema.json."""
    store = {}
    for path in sorted((root / SCHEMA_DIR).glob("*.schema.json")):
        store[path.name] = load_json(path)
    return store


def make_validator(name, store, schema_dir):
    """A validator for schema `name`, resolving references between the files
    of the store (jsonschema >= 4.18 uses 'referencing'; older, RefResolver)."""
    schema = store[name + ".schema.json"]
    cls = jsonschema.validators.validator_for(schema)
    try:
        import referencing
        import referencing.jsonschema
    except ImportError:
        def uri(file_name):
            return (schema_dir / file_name).as_uri()
        resolver = jsonschema.RefResolver(
            base_uri=uri(name + ".schema.json"), referrer=schema,
            store={uri(key): value for key, value in store.items()})
        return cls(schema, resolver=resolver)
    resources = [(key, referencing.Resource.from_contents(
        value, default_specification=referencing.jsonschema.DRAFT202012))
        for key, value in store.items()]
    return cls(schema, registry=referencing.Registry().with_resources(resources))


def pointer(parts):
    parts = [str(p).replace("~", "~0").replace("/", "~1") for p in parts]
    return "/" + "/".join(parts) if parts else "/"


def violations(validator, document):
    """[(JSON pointer, message)] of every violation, sorted by pointer."""
    found = []
    for error in validator.iter_errors(document):
        path = list(error.absolute_path)
        if error.validator == "additionalProperties" and isinstance(error.instance, dict):
            # Name the unexpected key itself, as xgauge does.
            known = set(error.schema.get("properties", {}))
            patterns = list(error.schema.get("patternProperties", {}))
            extra = sorted(k for k in error.instance
                           if k not in known and not any(re.search(p, k) for p in patterns))
            for key in extra or [None]:
                where = path + ([key] if key is not None else [])
                found.append((pointer(where), f"unknown key '{key}'" if key else error.message))
            continue
        if error.validator == "not" and error.validator_value == {} and path:
            # common.schema.json#/$defs/forbidden: a key of another variant.
            found.append((pointer(path), f"key '{path[-1]}' is not allowed here"))
            continue
        found.append((pointer(path), error.message))
    return sorted(found)


def broken_documents(root):
    """(label, schema, document, expected pointer): documents that must fail."""
    def read(relative):
        return load_json(root / relative)

    cases = []
    job = read("examples/prism_a_small_job.json")

    d = copy.deepcopy(job)
    d["dimensions"]["strat"] = d["dimensions"].pop("start")
    cases.append(("job: misspelled key", "job", d, "/dimensions/strat"))

    d = copy.deepcopy(job)
    d["seed"] = "1"
    cases.append(("job: seed of the wrong type", "job", d, "/seed"))

    d = copy.deepcopy(job)
    d["radiographs"][0]["distance_mm"] = 10.0
    cases.append(("job: distance_mm on a free radiograph", "job", d, "/radiographs/0/distance_mm"))

    d = copy.deepcopy(job)
    del d["radiographs"][1]["distance_mm"]
    cases.append(("job: translated radiograph without distance_mm", "job", d, "/radiographs/1"))

    d = read("examples/machine_4096.json")
    d["detector"]["columns"] = "4096"
    cases.append(("machine: columns as a string", "machine", d, "/detector/columns"))

    d = read("parts/prism_jaw.json")
    d["dimensions"][0]["unit"] = "cm"
    cases.append(("part model: unknown unit", "part_model", d, "/dimensions/0/unit"))

    d = read("parts/prism_jaw.json")
    d["shape"]["segments"] = 64
    cases.append(("part model: revolution key on an extrusion", "part_model", d, "/shape/segments"))

    d = read("examples/prism_a_pose.json")
    d["matrix"] = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]
    cases.append(("pose: both matrix and Euler angles", "pose", d, "/rotation_deg"))

    d = {"model": "exponential_sum", "terms": [{"weight": 1.0, "mu_per_mm": 0.1}],
         "compound": "Al"}
    cases.append(("material: monochromatic key on an exponential sum", "material", d, "/compound"))

    d = read("datasets/prism_a_small.json")
    d["shots"]["translations"]["cuont"] = d["shots"]["translations"].pop("count")
    cases.append(("recipe: misspelled key", "recipe", d, "/shots/translations/cuont"))

    d = read("examples/calibrate_wedge.json")
    del d["radiograph"]["flat"]
    cases.append(("wedge calibration: dark without flat", "calibrate_wedge", d, "/radiograph"))

    d = read("examples/study_prism_a.json")
    d["radiographs"] = []
    cases.append(("study: radiographs, which the dataset gives", "study", d, "/radiographs"))

    d = read("examples/step/bracket.json")
    del d["dimensions"][0]["offset"]["faces"]
    cases.append(("part model: an offset that names no faces", "part_model", d, "/dimensions/0/offset"))

    d = read("examples/step/bracket.json")
    d["dimensions"][6]["position"]["direction"] = [1, 0]
    # (one object or a list of them: the validator reports the object)
    cases.append(("part model: a position's direction of 2 numbers", "part_model", d,
                  "/dimensions/6/position"))

    d = read("examples/step/verify_bracket.json")
    d["measurements"] = d["measurements"][:2]
    cases.append(("verification: two measurements of the master", "verify", d, "/measurements"))

    d = read("examples/calibrate_prism_b.json")
    d["material"] = "aluminium_60kev.json"
    cases.append(("part calibration: material given", "calibrate_part", d, "/material"))

    d = copy.deepcopy(job)
    d["tolerances"] = {"width": {"nominal": 20.98, "lower": -0.02}}
    cases.append(("job: tolerance without upper", "job", d, "/tolerances/width"))

    d = read("parts/prism_jaw.json")
    d["dimensions"][0]["tolerance"] = {"nominal": 21.0, "lower": -0.05, "upper": 0.05}
    cases.append(("part model: tolerance with a nominal (the dimension's)", "part_model", d,
                  "/dimensions/0/tolerance/nominal"))

    d = read("examples/calibrate_prism_b.json")
    d["tolerances"] = {"size_x": {"lower": -0.1, "upper": 0.1}}
    cases.append(("part calibration: tolerances given", "calibrate_part", d, "/tolerances"))
    return cases


def accepted_documents(root):
    """(label, schema, document): documents with optional keys that no
    shipped file uses, which must pass."""
    def read(relative):
        return load_json(root / relative)

    cases = []
    d = read("examples/prism_a_small_job.json")
    d["tolerances"] = {"width": {"nominal": 20.98, "lower": -0.02, "upper": 0.02},
                       "thickness": {"lower": 0.01, "upper": 0.05}}
    cases.append(("job: tolerances", "job", d))

    d = read("examples/study_prism_a.json")
    d["tolerances"] = {"width": {"lower": -0.02, "upper": 0.02}}
    cases.append(("study: tolerances, passed to every run's job", "study", d))

    d = read("parts/prism_jaw.json")
    d["dimensions"][0]["tolerance"] = {"lower": -0.05, "upper": 0.05}
    cases.append(("part model: a dimension's default tolerance", "part_model", d))
    return cases


def main():
    root = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else
                        pathlib.Path(__file__).resolve().parent.parent).resolve()
    passed = failed = 0

    def fail(message):
        nonlocal failed
        failed += 1
        print("FAIL " + message)

    def ok(message):
        nonlocal passed
        passed += 1
        print("ok   " + message)

    store = load_schemas(root)
    if not store:
        print(f"validate_schemas.py: no schemas in {root / SCHEMA_DIR}", file=sys.stderr)
        return 2

    # The schemas themselves.
    for name, schema in store.items():
        try:
            jsonschema.validators.validator_for(schema).check_schema(schema)
            ok(f"{SCHEMA_DIR / name} is a valid schema")
        except jsonschema.exceptions.SchemaError as e:
            fail(f"{SCHEMA_DIR / name}: {pointer(e.absolute_path)}: {e.message}")

    validators = {}

    def validator(name):
        if name not in validators:
            validators[name] = make_validator(name, store, root / SCHEMA_DIR)
        return validators[name]

    # Every shipped file, by the table.
    for folder in FOLDERS:
        for path in sorted((root / folder).rglob("*.json")):
            relative = path.relative_to(root).as_posix()
            name = schema_for(relative)
            if name is None:
                fail(f"{relative}: no rule in tests/validate_schemas.py (RULES) says which "
                     "schema it must satisfy")
                continue
            if name + ".schema.json" not in store:
                fail(f"{relative}: schema {SCHEMA_DIR / (name + '.schema.json')} is missing")
                continue
            try:
                document = load_json(path)
            except (ValueError, UnicodeDecodeError) as e:
                fail(f"{relative}: not JSON: {e}")
                continue
            problems = violations(validator(name), document)
            if problems:
                for where, message in problems:
                    fail(f"{relative}: {where}: {message}")
            else:
                ok(f"{relative} ({name})")

    # The table must leave unknown kinds of file unmatched.
    for relative in ["examples/unknown_kind.json", "parts/sub/nested.json", "elsewhere/x.json"]:
        if schema_for(relative) is None:
            ok(f"no schema rule matches {relative}")
        else:
            fail(f"{relative} should match no rule, but matches '{schema_for(relative)}'")

    # Broken documents must be rejected, at the right place.
    try:
        cases = broken_documents(root)
    except (OSError, KeyError, ValueError) as e:
        cases = []
        fail(f"cannot build the broken documents from the shipped files: {e!r}")
    for label, name, document, expected in cases:
        problems = violations(validator(name), document)
        pointers = [where for where, _ in problems]
        if expected in pointers:
            ok(f"rejected: {label} ({expected})")
        elif problems:
            fail(f"{label}: rejected, but not at {expected}: {problems}")
        else:
            fail(f"{label}: accepted by {name}.schema.json")

    # Optional keys no shipped file uses must pass.
    try:
        accepted = accepted_documents(root)
    except (OSError, KeyError, ValueError) as e:
        accepted = []
        fail(f"cannot build the accepted documents from the shipped files: {e!r}")
    for label, name, document in accepted:
        problems = violations(validator(name), document)
        if problems:
            fail(f"{label}: rejected by {name}.schema.json: {problems}")
        else:
            ok(f"accepted: {label}")

    print(f"{passed} passed, {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
