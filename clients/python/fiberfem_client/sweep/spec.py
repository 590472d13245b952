"""The sweep file (docs/sweeps.md): read, checked key by key, and expanded into the
configurations to run. Every error names the key that is wrong (`SweepFileError`)."""

from __future__ import annotations

import itertools
import math
import os
import random
import re
from dataclasses import dataclass, field

import yaml

from .columns import COST_MEASURES, DEFAULT_ERRORS, ERROR_MEASURES


class SweepFileError(ValueError):
    """A sweep file that cannot be run; the message starts with the file and the key."""


# PyYAML reads YAML 1.1, where `1e-10` is a string; sweep files are YAML 1.2 like scene
# files (yaml-cpp): a float may have an exponent without a dot.
class _Loader(yaml.SafeLoader):
    pass


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
                    |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
                    |\.[0-9_]+(?:[eE][-+][0-9]+)?
                    |[-+]?\.(?:inf|Inf|INF)
                    |\.(?:nan|NaN|NAN))$""", re.X),
    list("-+0123456789."),
)

TOP_KEYS = {"sweep", "scene", "set", "groups", "reference", "errors", "cost", "goals", "sample_s",
            "timeout_s", "keep_archives", "prepare"}
GROUP_KEYS = {"name", "vary", "set", "combine", "sample"}
REFERENCE_KEYS = {"converged", "finest", "group", "set"}
# Which value of a swept key is the finest when `reference: {converged: true}` and the file
# does not say (`reference.finest`): smaller steps and tolerances, more cells.
DEFAULT_FINEST = {"solver.dt": "min", "solver.tolerance": "min", "mesh.cells": "max", "mesh.refine": "max",
                  "mesh.resolution": "max", "solver.max_iterations": "max"}
FINEST_CHOICES = ("min", "max", "base")
RANDOM_KINDS = ("uniform", "loguniform", "choice")


@dataclass(frozen=True)
class Configuration:
    """One run of the sweep: `overrides` are the `--set KEY=VALUE` texts, in order."""
    name: str
    group: str
    values: dict
    overrides: tuple


@dataclass
class Sweep:
    name: str
    path: str
    scene: str                        # absolute path, or builtin:NAME
    base_set: dict
    groups: list = field(default_factory=list)   # [(name, [values dict, ...], set dict)]
    reference: Configuration | None = None
    errors: list = field(default_factory=list)
    cost: str = "engine_s_per_sim_s"
    goals: list = field(default_factory=list)    # [(error, max)]
    sample_s: float = 1.0 / 30.0
    timeout_s: float = 3600.0
    keep_archives: bool = False
    prepare: list = field(default_factory=list)  # [(argv, creates)], paths from the file's folder

    def configurations(self) -> list:
        out = []
        for gname, points, gset in self.groups:
            for i, values in enumerate(points):
                name = gname if len(points) == 1 else f"{gname}/{i}"
                out.append(Configuration(name, gname, dict(values), overrides_of(self.base_set, gset, values)))
        return out


def format_value(v) -> str:
    """A value as `--set` reads it (YAML): shortest round-trip floats, flow-style lists."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(format_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k}: {format_value(x)}" for k, x in v.items()) + "}"
    return str(v)


def overrides_of(*layers) -> tuple:
    merged = {}
    for layer in layers:
        merged.update(layer)
    return tuple(f"{k}={format_value(v)}" for k, v in merged.items())


def _fail(where: str, what: str):
    raise SweepFileError(f"{where}: {what}")


def _mapping(node, where, allowed=None):
    if not isinstance(node, dict):
        _fail(where, f"must be a mapping, not {type(node).__name__}")
    if allowed is not None:
        for k in node:
            if k not in allowed:
                _fail(f"{where}.{k}" if where else str(k), f"unknown key (allowed: {', '.join(sorted(allowed))})")
    return node


def _scene_keys(node, where) -> dict:
    _mapping(node, where)
    for k, v in node.items():
        if not isinstance(k, str) or not re.fullmatch(r"[A-Za-z_][\w\[\]\.]*", k):
            _fail(f"{where}.{k}", "is not a scene key path (e.g. solver.dt, regions[0].material.E_L)")
        if v is None:
            _fail(f"{where}.{k}", "needs a value (a number, string, boolean, list or mapping)")
    return dict(node)


def _number(v, where, positive=False):
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        _fail(where, f"must be a finite number, not {v!r}")
    if positive and v <= 0:
        _fail(where, f"must be > 0, not {v!r}")
    return float(v)


def _pair(node, where):
    if not isinstance(node, list) or len(node) != 2:
        _fail(where, "must be a list of two numbers [low, high]")
    lo, hi = (_number(x, f"{where}[{i}]") for i, x in enumerate(node))
    if not lo < hi and not lo > hi:
        _fail(where, "low and high must differ")
    return lo, hi


def _axis_values(spec, where) -> list:
    """A swept key's values: a list, or {linear|log: [a, b], num: N}."""
    if isinstance(spec, list):
        if not spec:
            _fail(where, "an empty list of values")
        return list(spec)
    if isinstance(spec, dict):
        kinds = [k for k in ("linear", "log") if k in spec]
        _mapping(spec, where, {"linear", "log", "num"})
        if len(kinds) != 1:
            _fail(where, "a range needs exactly one of linear: [a, b] or log: [a, b], and num: N")
        num = spec.get("num")
        if not isinstance(num, int) or isinstance(num, bool) or num < 2:
            _fail(f"{where}.num", f"must be an integer >= 2, not {num!r}")
        a, b = _pair(spec[kinds[0]], f"{where}.{kinds[0]}")
        if kinds[0] == "log":
            if a <= 0 or b <= 0:
                _fail(f"{where}.log", "a log range needs positive ends")
            return [float(f"{a * (b / a) ** (i / (num - 1)):.12g}") for i in range(num)]
        return [float(f"{a + (b - a) * i / (num - 1):.12g}") for i in range(num)]
    _fail(where, "must be a list of values or a range {linear|log: [a, b], num: N}")


def _random_draw(spec, where):
    """A sampled key: {uniform|loguniform: [a, b]} or {choice: [...]} (a list is a choice)."""
    if isinstance(spec, list):
        spec = {"choice": spec}
    _mapping(spec, where, set(RANDOM_KINDS))
    if len(spec) != 1:
        _fail(where, "needs exactly one of uniform: [a, b], loguniform: [a, b], choice: [...]")
    kind, arg = next(iter(spec.items()))
    if kind == "choice":
        if not isinstance(arg, list) or not arg:
            _fail(f"{where}.choice", "must be a non-empty list")
        return lambda rng: rng.choice(arg)
    lo, hi = _pair(arg, f"{where}.{kind}")
    if kind == "loguniform":
        if lo <= 0 or hi <= 0:
            _fail(f"{where}.loguniform", "needs positive ends")
        return lambda rng: float(f"{math.exp(rng.uniform(math.log(lo), math.log(hi))):.12g}")
    return lambda rng: float(f"{rng.uniform(lo, hi):.12g}")


def _group_points(g, where) -> list:
    vary = dict(g.get("vary", {}))  # keys checked by _groups
    if "sample" in g:
        s = _mapping(g["sample"], f"{where}.sample", {"count", "seed"})
        count, seed = s.get("count"), s.get("seed", 0)
        if not isinstance(count, int) or isinstance(count, bool) or count < 1:
            _fail(f"{where}.sample.count", f"must be an integer >= 1, not {count!r}")
        if not isinstance(seed, int) or isinstance(seed, bool):
            _fail(f"{where}.sample.seed", f"must be an integer, not {seed!r}")
        if not vary:
            _fail(f"{where}.vary", "a sampled group needs keys to vary")
        draws = {k: _random_draw(v, f"{where}.vary.{k}") for k, v in vary.items()}
        rng = random.Random(seed)
        return [{k: d(rng) for k, d in draws.items()} for _ in range(count)]
    axes = {k: _axis_values(v, f"{where}.vary.{k}") for k, v in vary.items()}
    combine = g.get("combine", "grid")
    if combine not in ("grid", "zip"):
        _fail(f"{where}.combine", f"must be grid or zip, not {combine!r}")
    if not axes:
        return [{}]
    keys = list(axes)
    if combine == "zip":
        lengths = {len(v) for v in axes.values()}
        if len(lengths) != 1:
            _fail(f"{where}.vary", "combine: zip needs lists of one length")
        return [dict(zip(keys, vals)) for vals in zip(*axes.values())]
    return [dict(zip(keys, vals)) for vals in itertools.product(*axes.values())]


def _groups(node, where="groups") -> list:
    if not isinstance(node, list) or not node:
        _fail(where, "must be a non-empty list of groups")
    out, names = [], set()
    for i, g in enumerate(node):
        w = f"{where}[{i}]"
        _mapping(g, w, GROUP_KEYS)
        name = g.get("name")
        if not isinstance(name, str) or not re.fullmatch(r"[\w.+-]+", name):
            _fail(f"{w}.name", f"needs a name of letters, digits, . + - _ (got {name!r})")
        if name in names or name == "reference":
            _fail(f"{w}.name", f"'{name}' is used twice (or is the reserved name 'reference')")
        names.add(name)
        gset = _scene_keys(g.get("set", {}), f"{w}.set")
        if "vary" in g:
            _mapping(g["vary"], f"{w}.vary")
            _scene_keys({k: 0 for k in g["vary"]}, f"{w}.vary")
        out.append((name, _group_points(g, w), gset))
    return out


def _finest(values, how):
    if isinstance(values[0], dict):
        raise SweepFileError("mappings cannot be ordered: say base and give the reference's value in reference.set")
    measure = (lambda v: math.prod(v)) if isinstance(values[0], list) else (lambda v: v)
    try:
        return (min if how == "min" else max)(values, key=measure)
    except TypeError:
        raise SweepFileError(f"values {values!r} cannot be ordered: say base and give the reference's value "
                             "in reference.set") from None


def _reference(node, sweep: Sweep, where="reference") -> Configuration:
    if node == "converged":
        node = {"converged": True}
    _mapping(node, where, REFERENCE_KEYS)
    extra = _scene_keys(node.get("set", {}), f"{where}.set")
    if "group" in node:
        if node.get("converged"):
            _fail(where, "give either group or converged, not both")
        match = [g for g in sweep.groups if g[0] == node["group"]]
        if not match:
            _fail(f"{where}.group", f"no group named {node['group']!r}")
        name, points, gset = match[0]
        if len(points) != 1:
            _fail(f"{where}.group", f"group {name!r} has {len(points)} configurations; the reference must be one")
        return Configuration("reference", "reference", dict(points[0]),
                             overrides_of(sweep.base_set, gset, points[0], extra))
    if node.get("converged") is not True:
        if "converged" in node:
            _fail(f"{where}.converged", "must be true (or use group: NAME, or set: only)")
        return Configuration("reference", "reference", {}, overrides_of(sweep.base_set, extra))
    finest = _mapping(node.get("finest", {}), f"{where}.finest")
    axes = {}
    for _, points, _ in sweep.groups:
        for p in points:
            for k, v in p.items():
                axes.setdefault(k, [])
                if v not in axes[k]:
                    axes[k].append(v)
    for k, how in finest.items():
        if k not in axes:
            _fail(f"{where}.finest.{k}", "is not a swept key")
        if how not in FINEST_CHOICES:
            _fail(f"{where}.finest.{k}", f"must be one of {', '.join(FINEST_CHOICES)}, not {how!r}")
    values = {}
    for k, vals in axes.items():
        how = finest.get(k, DEFAULT_FINEST.get(k))
        if how is None:
            _fail(f"{where}.finest.{k}", "say which value of this swept key is the finest: min, max, or base "
                                         "(the scene's own value, or the one reference.set gives)")
        if how != "base":
            try:
                values[k] = _finest(vals, how)
            except SweepFileError as e:
                _fail(f"{where}.finest.{k}", str(e))
    return Configuration("reference", "reference", {**values, **extra}, overrides_of(sweep.base_set, values, extra))


def _entries(node, where, form, keys):
    """(where[i], entry) of a list of mappings with these keys."""
    if not isinstance(node, list):
        _fail(where, f"must be a list of {form}")
    for i, entry in enumerate(node):
        yield f"{where}[{i}]", _mapping(entry, f"{where}[{i}]", keys)


def _goals(node, errors, where="goals") -> list:
    out = []
    for w, g in _entries(node, where, "{error: NAME, max: VALUE}", {"error", "max"}):
        if g.get("error") not in errors:
            _fail(f"{w}.error", f"must be one of the sweep's errors ({', '.join(errors)}), not {g.get('error')!r}")
        out.append((g["error"], _number(g.get("max"), f"{w}.max", positive=True)))
    return out


def _prepare(node, where="prepare") -> list:
    out = []
    for w, step in _entries(node, where, "{run: [PROGRAM, ARG...], creates: FILE}", {"run", "creates"}):
        argv, creates = step.get("run"), step.get("creates")
        if not isinstance(argv, list) or not argv or not all(isinstance(a, (str, int, float)) for a in argv):
            _fail(f"{w}.run", "must be a non-empty list: the program and its arguments")
        if not isinstance(creates, str) or not creates:
            _fail(f"{w}.creates", "must name the file the step makes (the step is skipped when it exists)")
        out.append(([str(a) for a in argv], creates))
    return out


def parse_sweep(text: str, path: str) -> Sweep:
    """Reads and checks a sweep file's text; `path` names it in errors and anchors relative
    scene paths."""
    try:
        doc = yaml.load(text, Loader=_Loader)
    except yaml.YAMLError as e:
        raise SweepFileError(f"{path}: not YAML: {e}") from None
    try:
        return _parse(doc, path)
    except SweepFileError as e:
        raise SweepFileError(f"{path}: {e}") from None


def _parse(doc, path) -> Sweep:
    _mapping(doc, "", TOP_KEYS)
    for k in ("sweep", "scene", "groups"):
        if k not in doc:
            _fail(k, "is required")
    name = doc["sweep"]
    if not isinstance(name, str) or not re.fullmatch(r"[\w.+-]+", name):
        _fail("sweep", f"needs a name of letters, digits, . + - _ (got {name!r})")
    scene = doc["scene"]
    if not isinstance(scene, str) or not scene:
        _fail("scene", "must be a scene file path (relative to the sweep file) or builtin:NAME")
    if not scene.startswith("builtin:"):
        scene = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(path)), scene))
        if not os.path.isfile(scene):
            _fail("scene", f"no scene file at {scene}")
    sw = Sweep(name=name, path=os.path.abspath(path), scene=scene,
               base_set=_scene_keys(doc.get("set", {}), "set"))
    sw.groups = _groups(doc["groups"])
    sw.errors = list(doc.get("errors", DEFAULT_ERRORS if "reference" in doc else []))
    for i, e in enumerate(sw.errors):
        if e not in ERROR_MEASURES:
            _fail(f"errors[{i}]", f"unknown error measure {e!r} (known: {', '.join(ERROR_MEASURES)})")
    if sw.errors and "reference" not in doc:
        _fail("reference", "error measures need a reference (converged: true, group: NAME or set: {...})")
    if "reference" in doc:
        sw.reference = _reference(doc["reference"], sw)
    sw.cost = doc.get("cost", sw.cost)
    if sw.cost not in COST_MEASURES:
        _fail("cost", f"must be one of {', '.join(COST_MEASURES)}, not {sw.cost!r}")
    sw.goals = _goals(doc.get("goals", []), sw.errors)
    if "sample_s" in doc:
        sw.sample_s = _number(doc["sample_s"], "sample_s", positive=True)
    if "timeout_s" in doc:
        sw.timeout_s = _number(doc["timeout_s"], "timeout_s", positive=True)
    sw.prepare = _prepare(doc.get("prepare", []))
    if "keep_archives" in doc:
        if not isinstance(doc["keep_archives"], bool):
            _fail("keep_archives", f"must be true or false, not {doc['keep_archives']!r}")
        sw.keep_archives = doc["keep_archives"]
    return sw


def load_sweep(path: str) -> Sweep:
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except OSError as e:
        raise SweepFileError(f"{path}: cannot read: {e.strerror}") from None
    return parse_sweep(text, path)
