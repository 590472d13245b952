"""The Python client's DDS types (clients/python/fiberfem_client/types.py) against the IDL
they mirror (idl/*.idl): every struct of the IDL has a class with the same type name,
extensibility, members in the same order with the same types, and the same keys, and the
module has no class the IDL lacks. The IDL is read here with a small parser of its flat
structs (no unions, no nesting: DESIGN.md section 4). Exit 0 when they agree; otherwise each
difference is printed and the exit code is 1.

    python tests/idl/python_types_check.py IDL_DIR
"""

import re
import sys
import typing
from pathlib import Path

from cyclonedds.idl import IdlStruct

import fiberfem_client.types as py_types

SCALARS = {
    "string": "str", "boolean": "bool", "int16": "int16", "int32": "int32", "uint32": "uint32",
    "uint64": "uint64", "double": "float64", "float": "float32",
}


def parse_idl(text):
    """{typename: (extensibility, [(member, type), ...], {keys})} of the structs in `text`."""
    text = re.sub(r"//[^\n]*", "", text)
    module = re.search(r"module\s+(\w+)", text).group(1)
    structs = {}
    for m in re.finditer(r"(@\w+)?\s*struct\s+(\w+)\s*\{(.*?)\};", text, re.S):
        ext = (m.group(1) or "@final").lstrip("@")
        members, keys = [], set()
        for decl in m.group(3).split(";"):
            decl = decl.strip()
            if not decl:
                continue
            is_key = decl.startswith("@key")
            decl = decl.replace("@key", "").strip()
            t, name = decl.rsplit(None, 1)
            t = t.replace(" ", "")
            seq = re.fullmatch(r"sequence<(\w+)>", t)
            members.append((name, f"sequence[{SCALARS[seq.group(1)]}]" if seq else SCALARS[t]))
            if is_key:
                keys.add(name)
        structs[f"{module}::{m.group(2)}"] = (ext, members, keys)
    return structs


def python_type(hint):
    """The IDL-side name of a field's annotation in the Python binding."""
    if typing.get_origin(hint) is typing.Annotated:
        meta = typing.get_args(hint)[1:]
        for mark in meta:
            if not isinstance(mark, str):  # sequence[float32] and the like
                return str(mark).replace("'", "")
        return meta[0]
    return hint.__name__


def main(idl_dir):
    want = {}
    for f in sorted(Path(idl_dir).glob("*.idl")):
        want.update(parse_idl(f.read_text()))
    have = {c.__idl_typename__: c for c in vars(py_types).values()
            if isinstance(c, type) and issubclass(c, IdlStruct) and c is not IdlStruct}
    problems = []
    for name in sorted(set(want) - set(have)):
        problems.append(f"{name}: in the IDL, no class in fiberfem_client/types.py")
    for name in sorted(set(have) - set(want)):
        problems.append(f"{name}: a class in fiberfem_client/types.py, not in the IDL")
    for name in sorted(set(want) & set(have)):
        ext, members, keys = want[name]
        cls = have[name]
        if cls.__idl_annotations__.get("extensibility", "final") != ext:
            problems.append(f"{name}: extensibility {cls.__idl_annotations__.get('extensibility')} in Python, {ext} in the IDL")
        hints = typing.get_type_hints(cls, include_extras=True)
        got = [(m, python_type(h)) for m, h in hints.items()]
        if got != members:
            problems.append(f"{name}: members differ\n  IDL:    {members}\n  Python: {got}")
        py_keys = {m for m, a in cls.__idl_field_annotations__.items() if a.get("key")}
        if py_keys != keys:
            problems.append(f"{name}: keys {sorted(py_keys)} in Python, {sorted(keys)} in the IDL")
    for p in problems:
        print(p)
    print(f"{len(want)} IDL structs, {len(problems)} differences")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
