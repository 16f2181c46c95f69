"""YAML files read and written by YAML 1.2's number rules (configs, a run's config.yaml): PyYAML
alone reads YAML 1.1, where 1e-4 is a string and 020 is octal."""

from __future__ import annotations

import math
import re
from collections.abc import Hashable
from pathlib import Path

import yaml

from .regular_file import read_text


class _Loader(yaml.SafeLoader):
    """yaml.SafeLoader that reads numbers as YAML 1.2 does: 1e-4 as a float (YAML 1.1, PyYAML's,
    wants a dot, 1.0e-4, and reads 1e-4 as a string; .5e3 too), 020 as 20 (1.1: octal 16) and
    1:20 and 1:20.0 as strings (1.1: base 60, 80 and 80.0); and refuses a key given twice in
    one mapping (PyYAML keeps the last: a second `train:` section would drop the first) or a key
    that is a list or mapping."""

    def construct_mapping(self, node, deep=False):
        seen = set()
        for key_node, _ in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":
                continue
            key = self.construct_object(key_node, deep=deep)
            if not isinstance(key, Hashable):
                raise yaml.constructor.ConstructorError(
                    None, None, f"a key that is a {type(key).__name__}", key_node.start_mark
                )
            if key in seen:
                raise yaml.constructor.ConstructorError(
                    None, None, f"key '{key}' given twice in one mapping", key_node.start_mark
                )
            seen.add(key)
        return super().construct_mapping(node, deep)


_FLOAT, _INT = "tag:yaml.org,2002:float", "tag:yaml.org,2002:int"
# 1.5, .5, 1., 1e-4, .5e3, 1.5E+3, .inf, .nan
_FLOAT_12 = re.compile(
    r"^[-+]?(\.[0-9][0-9_]*|[0-9][0-9_]*\.[0-9_]*)([eE][-+]?[0-9]+)?$"
    r"|^[-+]?[0-9][0-9_]*[eE][-+]?[0-9]+$|^[-+]?\.(inf|Inf|INF)$|^\.(nan|NaN|NAN)$"
)
_INT_12 = re.compile(r"^[-+]?[0-9][0-9_]*$|^0o_*[0-7][0-7_]*$|^0x_*[0-9a-fA-F][0-9a-fA-F_]*$")
_Loader.yaml_implicit_resolvers = {
    first: [(tag, regexp) for tag, regexp in resolvers if tag not in (_INT, _FLOAT)]
    for first, resolvers in _Loader.yaml_implicit_resolvers.items()
}
_Loader.add_implicit_resolver(_FLOAT, _FLOAT_12, list("-+.0123456789"))
_Loader.add_implicit_resolver(_INT, _INT_12, list("-+0123456789"))


def _int_12(loader: _Loader, node) -> int:
    """A YAML 1.2 integer: decimal (leading zeros too), 0o octal or 0x hexadecimal."""
    text = loader.construct_scalar(node).replace("_", "")
    sign, digits = (-1, text[1:]) if text[0] == "-" else (1, text.lstrip("+"))
    base = {"0o": 8, "0x": 16}.get(digits[:2], 10)
    return sign * int(digits[2:] if base != 10 else digits, base)


_Loader.add_constructor(_INT, _int_12)


class _Dumper(yaml.SafeDumper):
    """yaml.SafeDumper that quotes what `_Loader` would read as a number (a method named 1e5 or
    0o17)."""


_Dumper.add_implicit_resolver(_FLOAT, _FLOAT_12, list("-+.0123456789"))
_Dumper.add_implicit_resolver(_INT, _INT_12, list("-+0123456789"))


def read_yaml(path: Path):
    """A YAML file read by the rules of config files (`_Loader`: YAML 1.2 numbers, no key given
    twice), as a run's config.yaml was written (`dump_yaml`); empty documents around its one
    (a closing `---`, which yaml.load refused as a second document) are left out."""
    documents = [d for d in yaml.load_all(read_text(path), Loader=_Loader) if d is not None]
    if len(documents) > 1:
        raise yaml.YAMLError(f"{len(documents)} YAML documents (split by ---): expected one")
    return documents[0] if documents else None


def yaml_text(value) -> str:
    """A config value as a message shows it: as `dump_yaml` writes it, on one line (null, true,
    2.5, [1, 2], {a: 1}), text quoted ('20', 'yes')."""
    if isinstance(value, str):
        return repr(value)
    text = yaml.dump(value, Dumper=_Dumper, default_flow_style=True, width=math.inf)
    return text.removesuffix("\n...\n").strip()


def dump_yaml(data: dict) -> str:
    """`data` as YAML that `_Loader` reads back as it is (a run's config.yaml)."""
    return yaml.dump(data, Dumper=_Dumper, sort_keys=False)
