#!/usr/bin/env python3
"""Files and functions stay small enough to read: every tracked source file under src, tools, python, bench and
tests has fewer than 800 lines, and every function in src and tools (free or member functions, constructors, lambdas,
test bodies) has at most 120, counted from the line of its name to its closing brace. The few exceptions are
in ALLOWED below, each with the reason it is longer.

Usage: size_test.py REPO_ROOT          the finder's self-test, then the check (exit 1 with the offenders)
       size_test.py --functions FILE   the functions the finder sees in one C++ file, with their lengths
"""
import pathlib
import re
import subprocess
import sys

MAX_FILE_LINES = 800  # a file this long or longer fails
MAX_FUNCTION_LINES = 120  # a function longer than this fails
FILE_DIRS = ("src", "tools", "python", "bench", "tests")
FUNCTION_DIRS = ("src", "tools")
CPP_SUFFIXES = {".cpp", ".hpp", ".h", ".cc", ".c"}
SOURCE_SUFFIXES = CPP_SUFFIXES | {".py", ".sh", ".html", ".js", ".cmake", ".txt"}

# Longer on purpose or for now: path (a file) or path:function (a function), and why.
ALLOWED = {
    "tools/perf-gate": "one self-contained script that CI runs by path and perf_gate_test.py loads by path; "
    "not yet split into a package",
}

CONTROL = {"if", "constexpr", "for", "while", "switch", "catch", "return", "sizeof", "alignof", "static_assert"}
# Words that may sit between a function's parameter list and its body, or wrap a part of the signature.
TRAILING = {"const", "noexcept", "override", "final", "mutable", "volatile", "constexpr", "consteval", "try"}
WRAPPERS = {"noexcept", "throw", "requires", "alignas", "__attribute__", "decltype"}


def blank_out(text):
    """The text with comments, string and character literals and preprocessor lines replaced by spaces
    (newlines kept, so positions and line numbers stay those of the file)."""
    out = list(text)
    i, n = 0, len(text)
    line_start = True

    def blank(a, b):
        for k in range(a, b):
            if out[k] != "\n":
                out[k] = " "

    while i < n:
        c = text[i]
        if line_start and c == "#":
            j = i
            while j < n and text[j] != "\n":
                j = j + 2 if text[j] == "\\" and j + 1 < n else j + 1  # a continued line goes on
            blank(i, j)
            i = j
            continue
        if c == "\n":
            line_start = True
            i += 1
            continue
        if not c.isspace():
            line_start = False
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            blank(i, j)
            i = j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            blank(i, j)
            i = j
        elif c == "R" and text.startswith('R"', i) and (i == 0 or not (text[i - 1].isalnum() or text[i - 1] == "_")):
            m = re.match(r'R"([^(\s]*)\(', text[i:])
            end = text.find(")" + m.group(1) + '"', i) if m else -1
            j = n if end < 0 else end + len(m.group(1)) + 2
            blank(i, j)
            i = j
        elif c in "\"'":
            if c == "'" and i > 0 and text[i - 1].isalnum():  # a digit separator (1'000)
                i += 1
                continue
            j = i + 1
            while j < n and text[j] != c and text[j] != "\n":
                j += 2 if text[j] == "\\" else 1
            blank(i + 1, j)
            i = j + 1
        else:
            i += 1
    return "".join(out)


def matching_open(code, close):
    """The position of the bracket that opens the one closed at `close` (scanning back), or -1."""
    pair = {")": "(", "]": "[", "}": "{", ">": "<"}[code[close]]
    depth = 0
    for k in range(close, -1, -1):
        if code[k] == code[close]:
            depth += 1
        elif code[k] == pair:
            depth -= 1
            if depth == 0:
                return k
    return -1


def word_before(code, pos):
    """(word, start) of the identifier (with :: and ~ qualifiers) that ends just before pos, skipping blanks."""
    k = pos - 1
    while k >= 0 and code[k].isspace():
        k -= 1
    end = k + 1
    while k >= 0 and (code[k].isalnum() or code[k] in "_:~"):
        k -= 1
    return code[k + 1 : end], k + 1


def skip_back_space(code, k):
    while k >= 0 and code[k].isspace():
        k -= 1
    return k


def init_list_start(code, p):
    """With p at the ',' or ':' before a member initializer, the position of the ')' that closes the
    constructor's parameter list (walking back over the other initializers), or -1 if it is no init list."""
    q = p
    while q >= 0 and code[q] == ",":
        q = skip_back_space(code, q - 1)
        if q < 0 or code[q] not in ")}":
            return -1
        q = skip_back_space(code, matching_open(code, q) - 1)
        _, ws = word_before(code, q + 1)
        q = skip_back_space(code, ws - 1)
    if q >= 1 and code[q] == ":" and code[q - 1] != ":":
        q = skip_back_space(code, q - 1)
        if q >= 0 and code[q] == ")":
            return q
    return -1


def function_name(code, brace):
    """The name of the function whose body opens at `brace`, with the position of the name, or None when the
    brace opens something else (a class, namespace, control statement, initializer)."""
    k = skip_back_space(code, brace - 1)
    # Trailing words and a trailing return type: `) const noexcept -> std::vector<int> {`.
    for _ in range(20):
        word, start = word_before(code, k + 1)
        if word in TRAILING:
            k = skip_back_space(code, start - 1)
            continue
        arrow = code.rfind("->", 0, k + 1)
        if arrow > 0 and code[arrow - 1] != "-" and ")" in code[:arrow] and not re.search(r"[;{}()]", code[arrow + 2 : k + 1]):
            # `) -> T {`: a trailing return type (no parentheses of its own; decltype(...) is handled below)
            before = skip_back_space(code, arrow - 1)
            if code[before] == ")" or word_before(code, before + 1)[0] in TRAILING:
                k = before
                continue
        break
    if k < 0:
        return None
    if code[k] == "]":  # `[&] {`: a lambda without a parameter list
        return ("<lambda>", matching_open(code, k))
    if code[k] == "}":  # the last of an init list is `m_{...}`
        open_brace = matching_open(code, k)
        _, ws = word_before(code, open_brace)
        p = skip_back_space(code, ws - 1)
        k = init_list_start(code, p) if p >= 0 and code[p] in ",:" else -1
        if k < 0:
            return None
    if code[k] != ")":
        return None
    # `(...) {` or a constructor's init list `X::X(...) : a_(x), b_{y} {`: walk back over the groups.
    while True:
        open_paren = matching_open(code, k)
        if open_paren < 0:
            return None
        before = skip_back_space(code, open_paren - 1)
        if before >= 0 and code[before] == "]":
            return ("<lambda>", matching_open(code, before))
        if before >= 0 and code[before] == ">":  # `f<T>(...)`, `operator<`
            lt = matching_open(code, before)
            if lt > 0:
                before = skip_back_space(code, lt - 1)
        if before >= 1 and code[before] == ")" and code[:before + 1].rstrip().endswith("operator()"):
            return ("operator()", code.rfind("operator", 0, before))
        word, start = word_before(code, before + 1)
        if not word:
            m = re.search(r"operator\s*\S{1,3}\s*$", code[max(0, open_paren - 20) : open_paren])
            if m:
                return ("operator", open_paren - 20 + m.start())
            return None
        if word in CONTROL:
            return None
        if word in WRAPPERS:  # `) noexcept(...) {`, `) -> decltype(...) {`
            k = skip_back_space(code, start - 1)
            if k >= 1 and code[k - 1 : k + 1] == "->":
                k = skip_back_space(code, k - 2)
            if k >= 0 and code[k] == ")":
                continue
            return None
        # A member initializer of an init list? Walk back over `, m(...)` / `, m{...}` to the ':'.
        p = skip_back_space(code, start - 1)
        if p >= 0 and code[p] in ",:" and not (code[p] == ":" and p > 0 and code[p - 1] == ":"):
            ctor = init_list_start(code, p)
            if ctor >= 0:
                k = ctor
                continue
            if code[p] == ":":  # after a label (`public:`, `case 1:`)
                return (word, start)
            return None
        return (word, start)


def functions(text):
    """(name, first line, last line) of every function body in a C++ text."""
    code = blank_out(text)
    line_of = []
    line = 1
    for ch in code:
        line_of.append(line)
        if ch == "\n":
            line += 1
    found = []
    stack = []
    for pos, ch in enumerate(code):
        if ch == "{":
            stack.append((pos, function_name(code, pos)))
        elif ch == "}" and stack:
            open_pos, named = stack.pop()
            if named is not None:
                name, start = named
                found.append((name, line_of[max(0, start)], line_of[pos]))
    return found


# The finder on the forms this code base uses; each function's body is padded to `pad` lines.
SELF_TEST = """
namespace hns::x {
struct Plain : public Base {
 public:
  explicit Plain(int a) : a_(a), b_{a, 2}, c_(std::max(a, 1)) {
PAD
  }
  int get() const noexcept { return a_; }
  ~Plain() override {
PAD
  }
  bool operator==(const Plain& o) const {
PAD
  }
  enum class Kind : uint8_t { kA, kB };
};
template <class T>
std::vector<T> Plain::multi_line(const std::vector<T>& values,
                                 std::span<const int> order,  // a comment with a { brace
                                 int k) const -> std::vector<T> {
  const char* s = "a string with { and }";
  if (k > 0) {
PAD
  } else if (k < 0) {
  } else {
  }
  for (int i : order) {
    while (i > 0) { --i; }
  }
  switch (k) {
    case 1: {
      break;
    }
  }
  try {
  } catch (const std::exception& e) {
  }
  auto add = [&](int a, int b) mutable -> int {
PAD
  };
  auto none = [] {
PAD
  };
  std::vector<int> v{1, 2, 3};
  return {};
}
Plain::Plain(const Other& o, int n)
    : Plain(n),
      d_{o.d} {
PAD
}
TEST(Plain, Works) {
PAD
}
auto tail() -> decltype(std::declval<int>()) {
PAD
}
}  // namespace hns::x
"""
SELF_TEST_EXPECTED = {"Plain": 1, "get": 1, "~Plain": 1, "operator": 1, "Plain::multi_line": 1, "<lambda>": 2,
                      "Plain::Plain": 1, "TEST": 1, "tail": 1}


def self_test():
    pad = MAX_FUNCTION_LINES
    text = SELF_TEST.replace("PAD", "\n".join(["  x += 1;"] * pad))
    found = functions(text)
    names = {}
    for name, _, _ in found:
        names[name] = names.get(name, 0) + 1
    problems = []
    if names != SELF_TEST_EXPECTED:
        problems.append(f"self-test: the finder saw {names}, not {SELF_TEST_EXPECTED}")
    long_ones = {name for name, a, b in found if b - a + 1 > MAX_FUNCTION_LINES}
    if long_ones != set(SELF_TEST_EXPECTED) - {"get"}:
        problems.append(f"self-test: too long: {sorted(long_ones)}, expected all but get")
    return problems


def tracked(root, dirs):
    out = subprocess.run(["git", "-C", str(root), "ls-files", "-z", "--", *dirs], capture_output=True, check=True)
    return [p for p in out.stdout.decode().split("\0") if p]


def is_source(root, rel):
    path = root / rel
    if path.suffix in SOURCE_SUFFIXES or path.name == "CMakeLists.txt":
        return path.suffix != ".txt" or path.name == "CMakeLists.txt"
    if path.suffix:
        return False
    try:
        with open(path, "rb") as f:
            return f.read(2) == b"#!"  # an extensionless script (tools/perf-gate, tools/test)
    except OSError:
        return False


def main():
    if len(sys.argv) == 3 and sys.argv[1] == "--functions":
        for name, a, b in functions(pathlib.Path(sys.argv[2]).read_text(errors="replace")):
            print(f"{b - a + 1:5d}  {a:5d}-{b:<5d} {name}")
        return 0
    root = pathlib.Path(sys.argv[1])
    failures = self_test()
    used = set()
    for rel in tracked(root, FILE_DIRS):
        if not is_source(root, rel) or not (root / rel).is_file():
            continue
        lines = (root / rel).read_text(errors="replace").count("\n")
        if lines >= MAX_FILE_LINES:
            if rel in ALLOWED:
                used.add(rel)
            else:
                failures.append(f"{rel}: {lines} lines (a source file must stay under {MAX_FILE_LINES})")
    for rel in tracked(root, FUNCTION_DIRS):
        if pathlib.PurePath(rel).suffix not in CPP_SUFFIXES:
            continue
        for name, a, b in functions((root / rel).read_text(errors="replace")):
            length = b - a + 1
            if length <= MAX_FUNCTION_LINES:
                continue
            key = f"{rel}:{name}"
            if key in ALLOWED:
                used.add(key)
            else:
                failures.append(f"{rel}:{a}: {name} is {length} lines (at most {MAX_FUNCTION_LINES})")
    for key in sorted(set(ALLOWED) - used):
        failures.append(f"allow list: {key} is no longer too long (or gone): remove it from ALLOWED")
    for f in failures:
        print(f)
    if failures:
        print(f"{len(failures)} problem(s); split the file or function by job, or add it to ALLOWED in "
              f"{pathlib.PurePath(__file__).name} with the reason")
        return 1
    print(f"ok: no source file of {', '.join(FILE_DIRS)} reaches {MAX_FILE_LINES} lines and no function of "
          f"{', '.join(FUNCTION_DIRS)} has more than {MAX_FUNCTION_LINES} ({len(ALLOWED)} allowed)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
