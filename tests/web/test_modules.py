"""The page's scripts (web/*.js, ES modules served without a build step) import one another
without a cycle: each view can be read before the views that use it, and a view that must
redraw after another subscribes to the page's events (web/bus.js) instead of importing it.

The imports are read from the scripts' tokens: static ``import ... from "./x.js"``,
``import "./x.js"``, ``export ... from "./x.js"`` and dynamic ``import("./x.js")``. Comments
are skipped (a JSDoc type's ``import("./x.js").T`` is no import at run time), and so are the
insides of strings, template literals and regular expressions.
"""

from __future__ import annotations

import re
from pathlib import Path

from tests.paths import ROOT
from tests.support.graphs import cycles

WEB = ROOT / "web"

_PUNCTUATION = re.compile(r">>>=|\.\.\.|===|!==|\*\*=|<<=|>>=|>>>|=>|==|!=|<=|>=|&&|\|\||\?\?|\?\.|"
                          r"\+\+|--|[-+*/%&|^]=|<<|>>|\*\*|[{}()\[\];,<>+\-*/%&|^!~?:=.@#]")
_WORD = re.compile(r"[A-Za-z_$\d][\w$]*(?:\.\d+)?")
#: After these tokens a ``/`` starts a regular expression, not a division.
_BEFORE_REGEX_WORDS = {"return", "typeof", "instanceof", "in", "of", "new", "delete", "void",
                       "throw", "case", "do", "else", "yield", "await"}


class _Scanner:
    """The tokens of a script: words, punctuation, and string literals as ``("str", value)``
    (a template literal's text is skipped, its ``${...}`` expressions scanned)."""

    def __init__(self, text: str) -> None:
        self.text = text
        self.i = 0
        self.tokens: list[tuple[str, str]] = []

    def scan(self, until_brace: bool = False) -> None:
        """Scan code up to the end, or (inside ``${``) up to its closing brace."""
        text, depth = self.text, 0
        while self.i < len(text):
            c = text[self.i]
            if c.isspace():
                self.i += 1
            elif text.startswith("//", self.i):
                end = text.find("\n", self.i)
                self.i = len(text) if end < 0 else end
            elif text.startswith("/*", self.i):
                end = text.find("*/", self.i + 2)
                self.i = len(text) if end < 0 else end + 2
            elif c in "\"'":
                self._string(c)
            elif c == "`":
                self._template()
            elif c == "/" and self._regex_allowed():
                self._regex()
            elif until_brace and c == "}" and depth == 0:
                self.i += 1
                return
            elif (word := _WORD.match(text, self.i)) is not None:
                self.tokens.append(("word", word.group()))
                self.i = word.end()
            else:
                punct = _PUNCTUATION.match(text, self.i)
                token = punct.group() if punct else c
                depth += (token == "{") - (token == "}")
                self.tokens.append(("punct", token))
                self.i += len(token)

    def _regex_allowed(self) -> bool:
        if not self.tokens:
            return True
        kind, value = self.tokens[-1]
        if kind == "punct":
            return value not in {")", "]", "}"}
        return kind == "word" and value in _BEFORE_REGEX_WORDS

    def _string(self, quote: str) -> None:
        text, j, value = self.text, self.i + 1, []
        while j < len(text) and text[j] != quote:
            if text[j] == "\\":
                j += 1
            value.append(text[j] if j < len(text) else "")
            j += 1
        self.tokens.append(("str", "".join(value)))
        self.i = j + 1

    def _template(self) -> None:
        text = self.text
        self.i += 1
        while self.i < len(text) and text[self.i] != "`":
            if text[self.i] == "\\":
                self.i += 2
            elif text.startswith("${", self.i):
                self.i += 2
                self.scan(until_brace=True)
            else:
                self.i += 1
        self.i += 1
        self.tokens.append(("template", ""))

    def _regex(self) -> None:
        text, j, in_class = self.text, self.i + 1, False
        while j < len(text) and (in_class or text[j] != "/") and text[j] != "\n":
            if text[j] == "\\":
                j += 1
            elif text[j] == "[":
                in_class = True
            elif text[j] == "]":
                in_class = False
            j += 1
        flags = _WORD.match(text, j + 1)
        self.i = flags.end() if flags else j + 1
        self.tokens.append(("regex", ""))


def _from_clause(rest: list[tuple[str, str]]) -> str | None:
    """The specifier of the statement's ``from "x"``, if it has one before it ends."""
    for j, token in enumerate(rest[:-1]):
        if token == ("punct", ";") or (token[0] == "word" and token[1] in {"import", "export"}):
            return None
        if token == ("word", "from") and rest[j + 1][0] == "str":
            return rest[j + 1][1]
    return None


def imported_specifiers(text: str) -> list[str]:
    """The module specifiers a script imports, in order: static imports, re-exports and
    dynamic ``import("...")`` with a literal specifier."""
    scanner = _Scanner(text)
    scanner.scan()
    tokens = scanner.tokens
    found: list[str] = []
    for k, (kind, value) in enumerate(tokens):
        if kind != "word" or value not in {"import", "export"}:
            continue
        if k > 0 and tokens[k - 1] == ("punct", "."):
            continue  # a property named import
        rest = tokens[k + 1:]
        spec: str | None = None
        if value == "import" and rest[:1] == [("punct", "(")] and rest[1:2] and rest[1][0] == "str":
            spec = rest[1][1]  # import("x")
        elif value == "import" and rest[:1] and rest[0][0] == "str":
            spec = rest[0][1]  # import "x"
        elif value == "import" or rest[:1] in ([("punct", "{")], [("punct", "*")]):
            spec = _from_clause(rest)  # import ... from "x", export {...} / * from "x"
        if spec is not None:
            found.append(spec)
    return found


def module_graph(web: Path = WEB) -> dict[str, set[str]]:
    """Script -> the scripts of the same folder it imports (``./x.js``), by file name."""
    graph: dict[str, set[str]] = {}
    for path in sorted(web.glob("*.js")):
        specs = imported_specifiers(path.read_text())
        graph[path.name] = {s.removeprefix("./") for s in specs
                            if s.startswith("./") and "/" not in s.removeprefix("./")}
    return graph


def test_the_page_has_no_import_cycle() -> None:
    graph = module_graph()
    assert graph.get("main.js"), "the page's scripts were not found or not read"
    assert cycles(graph) == []


def test_every_import_names_a_script_of_the_page() -> None:
    """An import the graph would drop (a typo, a script moved) is caught here rather than
    hiding a cycle."""
    graph = module_graph()
    assert sorted((name, target) for name, targets in graph.items() for target in targets
                  if target not in graph) == []


def test_the_parser_reads_every_import_form_and_skips_the_rest() -> None:
    text = '''// @ts-check
import { a, b } from "./a.js";
import * as c from './c.js';
import "./side.js";
import d, {
  e,
} from "./d.js"
export { f } from "./f.js";
export const from = 1, h = "./nor.js";
export * from "./g.js";
/** @type {import("./typeonly.js").T} */
// import { x } from "./commented.js";
const s = "import { y } from './instring.js'";
const t = `text ${import("./dynamic.js")} and ${`${"./nested"}`} import("./intemplate.js")`;
const r = /import\\("\\.\\/inregex\\.js"\\)/g, q = 4 / 2 / 1;
export function later() { return import("./lazy.js").then((m) => m.run(from, "./not.js")); }
const meta = import.meta.url;
'''
    assert imported_specifiers(text) == ["./a.js", "./c.js", "./side.js", "./d.js", "./f.js",
                                         "./g.js", "./dynamic.js", "./lazy.js"]


def test_the_checker_names_a_planted_cycle(tmp_path: Path) -> None:
    """Three scripts closing a cycle (one through a dynamic import) are reported with the
    path round it; a script outside it is not."""
    (tmp_path / "a.js").write_text('import { b } from "./b.js";\n')
    (tmp_path / "b.js").write_text('export const b = () => import("./c.js");\n')
    (tmp_path / "c.js").write_text('import { a } from "./a.js";\nimport "./d.js";\n')
    (tmp_path / "d.js").write_text('import { $ } from "./dom.js";\n')
    graph = module_graph(tmp_path)
    assert graph == {"a.js": {"b.js"}, "b.js": {"c.js"}, "c.js": {"a.js", "d.js"},
                     "d.js": {"dom.js"}}
    assert cycles(graph) == ["a.js, b.js, c.js: a.js -> b.js -> c.js -> a.js"]
