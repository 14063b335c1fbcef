"""A small, safe evaluator for the part models' dimension expressions.

docs/formats.md says expressions are in muparser syntax: + - * / ^,
comparisons, ``cond ? a : b``, ``&&`` and ``||``, functions (min, max, sum,
avg, abs, sqrt, exp, ln, log10, sin, cos, tan, asin, acos, atan, atan2, the
degree helpers sind, cosd, tand, asind, acosd, atand, atan2d, rad, deg) and
the constant pi.  Python's own parser would read ``^`` as exclusive-or and
cannot read ``?:``, so this is a hand-written recursive-descent parser that
builds a tree of plain Python closures: no ``eval``, no attribute access, no
names other than the ones given.

Precedence, lowest first: ``?:`` (right-assoc), ``||``, ``&&``,
comparisons (``== != < <= > >=``), ``+ -``, ``* /``, unary ``+ -``, ``^``
(right-assoc, binds tighter than unary minus, so ``-2^2`` is -4 as in
mathematics).  A single ``=`` is rejected, as xgauge does.
"""

import math
import re

__all__ = ["ExpressionError", "parse", "evaluate", "FUNCTIONS", "CONSTANTS"]


class ExpressionError(ValueError):
    pass


def _avg(*a):
    if not a:
        raise ExpressionError("avg() needs at least one argument")
    return sum(a) / len(a)


FUNCTIONS = {
    "min": (min, -1), "max": (max, -1), "sum": (lambda *a: float(sum(a)), -1), "avg": (_avg, -1),
    "abs": (abs, 1), "sqrt": (math.sqrt, 1), "exp": (math.exp, 1), "ln": (math.log, 1),
    "log": (math.log, 1), "log10": (math.log10, 1), "log2": (math.log2, 1),
    "sin": (math.sin, 1), "cos": (math.cos, 1), "tan": (math.tan, 1),
    "asin": (math.asin, 1), "acos": (math.acos, 1), "atan": (math.atan, 1),
    "sinh": (math.sinh, 1), "cosh": (math.cosh, 1), "tanh": (math.tanh, 1),
    "atan2": (math.atan2, 2),
    "sind": (lambda x: math.sin(math.radians(x)), 1),
    "cosd": (lambda x: math.cos(math.radians(x)), 1),
    "tand": (lambda x: math.tan(math.radians(x)), 1),
    "asind": (lambda x: math.degrees(math.asin(x)), 1),
    "acosd": (lambda x: math.degrees(math.acos(x)), 1),
    "atand": (lambda x: math.degrees(math.atan(x)), 1),
    "atan2d": (lambda y, x: math.degrees(math.atan2(y, x)), 2),
    "rad": (math.radians, 1), "deg": (math.degrees, 1),
    "sign": (lambda x: float((x > 0) - (x < 0)), 1),
    "rint": (lambda x: float(round(x)), 1),
}
CONSTANTS = {"pi": math.pi, "_pi": math.pi, "_e": math.e}

_TOKEN = re.compile(r"""
    (?P<ws>\s+)
  | (?P<num>(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)
  | (?P<name>[A-Za-z_][A-Za-z0-9_]*)
  | (?P<op>\|\||&&|==|!=|<=|>=|[-+*/^()<>?:,=])
""", re.VERBOSE)


def _tokenize(text):
    pos, out = 0, []
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if not m:
            raise ExpressionError(f"unexpected character {text[pos]!r} at {pos} in {text!r}")
        pos = m.end()
        kind = m.lastgroup
        if kind == "ws":
            continue
        if kind == "op" and m.group() == "=":
            raise ExpressionError(f"assignment '=' is not allowed (compare with '=='): {text!r}")
        out.append((kind, m.group()))
    out.append(("end", ""))
    return out


class _Parser:
    def __init__(self, text):
        self.text = text
        self.toks = _tokenize(text)
        self.i = 0
        self.names = set()

    def peek(self):
        return self.toks[self.i]

    def take(self, value=None):
        tok = self.toks[self.i]
        if value is not None and tok[1] != value:
            raise ExpressionError(f"expected {value!r}, found {tok[1]!r} in {self.text!r}")
        self.i += 1
        return tok

    def parse(self):
        node = self.ternary()
        if self.peek()[0] != "end":
            raise ExpressionError(f"unexpected {self.peek()[1]!r} in {self.text!r}")
        return node

    def ternary(self):
        cond = self.logic_or()
        if self.peek()[1] == "?":
            self.take("?")
            a = self.ternary()
            self.take(":")
            b = self.ternary()
            return lambda env, c=cond, a=a, b=b: a(env) if c(env) != 0 else b(env)
        return cond

    def _binary(self, sub, ops):
        node = sub()
        while self.peek()[1] in ops:
            op = self.take()[1]
            rhs = sub()
            node = ops[op](node, rhs)
        return node

    def logic_or(self):
        return self._binary(self.logic_and, {
            "||": lambda a, b: (lambda env: float(a(env) != 0 or b(env) != 0))})

    def logic_and(self):
        return self._binary(self.compare, {
            "&&": lambda a, b: (lambda env: float(a(env) != 0 and b(env) != 0))})

    def compare(self):
        return self._binary(self.additive, {
            "==": lambda a, b: (lambda env: float(a(env) == b(env))),
            "!=": lambda a, b: (lambda env: float(a(env) != b(env))),
            "<": lambda a, b: (lambda env: float(a(env) < b(env))),
            "<=": lambda a, b: (lambda env: float(a(env) <= b(env))),
            ">": lambda a, b: (lambda env: float(a(env) > b(env))),
            ">=": lambda a, b: (lambda env: float(a(env) >= b(env))),
        })

    def additive(self):
        return self._binary(self.multiplicative, {
            "+": lambda a, b: (lambda env: a(env) + b(env)),
            "-": lambda a, b: (lambda env: a(env) - b(env)),
        })

    def multiplicative(self):
        def div(a, b):
            def f(env):
                den = b(env)
                if den == 0:
                    raise ExpressionError(f"division by zero in {self.text!r}")
                return a(env) / den
            return f
        return self._binary(self.unary, {"*": lambda a, b: (lambda env: a(env) * b(env)), "/": div})

    def unary(self):
        tok = self.peek()
        if tok[1] == "-":
            self.take()
            sub = self.unary()
            return lambda env: -sub(env)
        if tok[1] == "+":
            self.take()
            return self.unary()
        return self.power()

    def power(self):
        base = self.primary()
        if self.peek()[1] == "^":
            self.take()
            exponent = self.unary()  # right-associative; allows 2^-1
            return lambda env: float(base(env)) ** exponent(env)
        return base

    def primary(self):
        kind, text = self.take()
        if kind == "num":
            value = float(text)
            return lambda env: value
        if kind == "name":
            if self.peek()[1] == "(":
                if text not in FUNCTIONS:
                    raise ExpressionError(f"unknown function {text!r} in {self.text!r}")
                fn, arity = FUNCTIONS[text]
                self.take("(")
                args = []
                if self.peek()[1] != ")":
                    args.append(self.ternary())
                    while self.peek()[1] == ",":
                        self.take()
                        args.append(self.ternary())
                self.take(")")
                if arity >= 0 and len(args) != arity:
                    raise ExpressionError(f"{text}() takes {arity} argument(s) in {self.text!r}")
                if arity < 0 and not args:
                    raise ExpressionError(f"{text}() needs arguments in {self.text!r}")
                return lambda env, fn=fn, args=args: float(fn(*[a(env) for a in args]))
            if text in CONSTANTS:
                value = CONSTANTS[text]
                return lambda env: value
            self.names.add(text)

            def lookup(env, name=text):
                try:
                    return env[name]
                except KeyError:
                    raise ExpressionError(f"unknown name {name!r} in {self.text!r}") from None
            return lookup
        if text == "(":
            node = self.ternary()
            self.take(")")
            return node
        raise ExpressionError(f"unexpected {text!r} in {self.text!r}")


_CACHE = {}


def parse(text):
    """Compile an expression (string or number) into a function of a dict."""
    if isinstance(text, bool):
        raise ExpressionError(f"expected a number or an expression, got {text!r}")
    if isinstance(text, (int, float)):
        value = float(text)
        return lambda env: value
    if not isinstance(text, str):
        raise ExpressionError(f"expected a number or an expression, got {text!r}")
    if text not in _CACHE:
        _CACHE[text] = _Parser(text).parse()
    return _CACHE[text]


def evaluate(text, env=None):
    value = parse(text)(env or {})
    if not math.isfinite(value):
        raise ExpressionError(f"{text!r} is not finite ({value})")
    return float(value)
