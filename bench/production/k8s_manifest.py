#!/usr/bin/env python3
"""Checks docs/production.md's Kubernetes manifests (its yaml blocks) against
the Kubernetes API's schema as Debian 12's python3-kubernetes carries it
(22.6: the models generated from Kubernetes 1.22's OpenAPI spec): every
field known at its place, every value of its type, the required fields
present. Debian 12 ships no kubeconform, and its kubectl (kubernetes-client
1.20) validates, dry run or not, only against a running API server, which
Debian 12 does not ship. Usage:
  /usr/bin/python3 bench/production/k8s_manifest.py [DOCS]
Needs python3-kubernetes (apt install python3-kubernetes; or its .deb
unpacked with `dpkg -x` and PYTHONPATH pointing at its dist-packages)."""
import importlib.util
import os
import re
import sys
import types

import yaml

root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
docs = sys.argv[1] if len(sys.argv) > 1 else os.path.join(root, "docs", "production.md")

spec = importlib.util.find_spec("kubernetes")
if spec is None or not spec.submodule_search_locations:
    sys.exit("k8s_manifest: error: no python3-kubernetes (the schema's models): apt install python3-kubernetes")
# Only the generated models are needed: skip the package's __init__, which
# loads the API client's transports (google-auth, websocket, ...).
package = types.ModuleType("kubernetes")
package.__path__ = list(spec.submodule_search_locations)
sys.modules["kubernetes"] = package
import kubernetes.client as client  # noqa: E402
import kubernetes.client.models as models  # noqa: E402

KINDS = {("batch/v1", "Job"): "V1Job", ("v1", "ConfigMap"): "V1ConfigMap",
         ("v1", "PersistentVolumeClaim"): "V1PersistentVolumeClaim"}
errors = []


def required(cls, attribute):
    """Whether the model refuses None for an attribute (its required fields)."""
    obj = cls.__new__(cls)
    obj.local_vars_configuration = client.Configuration()
    obj.local_vars_configuration.client_side_validation = True
    try:
        setattr(obj, attribute, None)
    except ValueError:
        return True
    return False


def check(value, kind, where):
    if kind.startswith("list["):
        if not isinstance(value, list):
            errors.append(f"{where}: not a list")
            return
        for i, item in enumerate(value):
            check(item, kind[5:-1], f"{where}[{i}]")
    elif kind.startswith("dict("):
        if not isinstance(value, dict):
            errors.append(f"{where}: not a map")
            return
        item_kind = re.fullmatch(r"dict\(str, (.*)\)", kind).group(1)
        for key, item in value.items():
            check(item, item_kind, f"{where}.{key}")
    elif kind == "str":
        if not isinstance(value, str):
            errors.append(f"{where}: {value!r} is not a string")
    elif kind == "int":
        if not isinstance(value, int) or isinstance(value, bool):
            errors.append(f"{where}: {value!r} is not an integer")
    elif kind == "bool":
        if not isinstance(value, bool):
            errors.append(f"{where}: {value!r} is not a boolean")
    elif kind in ("object", "datetime", "float", "date"):
        pass
    else:
        cls = getattr(models, kind)
        if not isinstance(value, dict):
            errors.append(f"{where}: not an object ({kind})")
            return
        attribute = {json: attr for attr, json in cls.attribute_map.items()}
        for key, item in value.items():
            if key not in attribute:
                errors.append(f"{where}: unknown field '{key}' in {kind}")
            else:
                check(item, cls.openapi_types[attribute[key]], f"{where}.{key}")
        for attr, json in cls.attribute_map.items():
            if json not in value and required(cls, attr):
                errors.append(f"{where}: required field '{json}' missing in {kind}")


blocks = re.findall(r"```yaml\n(.*?)```", open(docs).read(), re.S)
if not blocks:
    sys.exit(f"k8s_manifest: error: no yaml block in {docs}")
count = 0
for b, block in enumerate(blocks, 1):
    for d, doc in enumerate(yaml.safe_load_all(block), 1):
        where = f"{os.path.basename(docs)} yaml block {b} document {d}"
        key = (doc.get("apiVersion"), doc.get("kind"))
        if key not in KINDS:
            errors.append(f"{where}: no schema here for apiVersion {key[0]} kind {key[1]}")
            continue
        check(doc, KINDS[key], f"{where} ({key[1]} {doc.get('metadata', {}).get('name', '')})")
        count += 1
version = getattr(sys.modules.get("kubernetes.client"), "__version__", "?")
for e in errors:
    print("k8s_manifest:", e, file=sys.stderr)
print(f"k8s_manifest: {count} manifest(s) of {docs} against python3-kubernetes {version}'s schema: "
      + ("valid" if not errors else f"{len(errors)} error(s)"))
sys.exit(1 if errors else 0)
