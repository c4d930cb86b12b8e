#!/usr/bin/env python3
"""Check that README.md's command synopsis lists exactly the flags `optinav ... --help` lists.

Usage: check_readme_synopsis.py OPTINAV README.md     self-test, then check README.md
       check_readme_synopsis.py --self-test OPTINAV   self-test only

The synopsis is the first ``` block under "## Commands". An entry starts with a line
`optinav <command> [<subcommand>] ...` and goes on over the indented lines below it; its command
is the run of lowercase words after `optinav`. A non-indented line that does not start with
`optinav` is a note: the flags it names apply to every command that takes options (e.g. `--log-level`), or, when it starts
`Label (command, command and command):`, to the commands in the parentheses only (e.g. the GNSS
fusion flags of `vio` and `bench gnss`). Indented lines below a note continue it.

Commands are discovered from `optinav --help` (the "commands" list), from each help's
"Subcommands:" list, from `optinav <path>` mentions in help texts (e.g. `sim suite`, `bench gnss`)
and from the README's entries; a path counts as a command when `optinav <path> --help` exits 0.

For every command the check reports each flag `--help` lists that its synopsis entry (with the
notes) does not name, each flag the entry or a note names that `--help` does not know, commands
without an entry and entries for commands that do not exist. `-h`/`--help` are exempt.
Exit 0 when all agree, 1 otherwise (each problem on its own line), 2 on bad usage.

The self-test builds a synopsis from the real help texts, checks that it passes, then plants one
mistake at a time (a flag dropped, an unknown flag, the note dropped, an entry dropped, an entry
for a command that does not exist, a scoped note with flags and a command its commands do not know) and checks that exactly that mistake is reported.
"""

import re
import subprocess
import sys

EXEMPT = {"-h", "--help"}
HELP_FLAG_RE = re.compile(r"^  (?:(-[A-Za-z0-9]),)?(--?[A-Za-z0-9][A-Za-z0-9-]*)")
TEXT_FLAG_RE = re.compile(r"(?<![\w-])(--[a-z0-9][a-z0-9-]*)")
MENTION_RE = re.compile(r"\boptinav((?: [a-z][a-z0-9-]*)+)")


class Help:
    def __init__(self, optinav):
        self.optinav = optinav
        self.cache = {}

    def get(self, path):
        """(exit code, text) of `optinav <path> --help`."""
        if path not in self.cache:
            proc = subprocess.run([self.optinav, *path.split(), "--help"], capture_output=True,
                                  text=True, timeout=60)
            self.cache[path] = (proc.returncode, proc.stdout + proc.stderr)
        return self.cache[path]

    def is_command(self, path):
        rc, text = self.get(path)
        if rc != 0:
            return False
        usage = re.search(r"^Usage: optinav((?: [a-z][a-z0-9-]*)*)", text, re.M)
        # A command without a usage line (e.g. `version`) is taken as it is; one whose usage line
        # names another path (extra words ignored by CLI11) is not a command.
        return usage is None or usage.group(1).strip() == path

    def takes_options(self, path):
        """False for a command whose help has no 'Options:' section (e.g. `version`)."""
        return bool(re.search(r"^(?:\S.*)?Options:\s*$", self.get(path)[1], re.M))

    def flags(self, path):
        _, text = self.get(path)
        found = set()
        in_options = False
        for line in text.splitlines():
            if re.match(r"^\S", line):
                in_options = line.rstrip().endswith("Options:")
                continue
            if in_options:
                m = HELP_FLAG_RE.match(line)
                if m:
                    found.update(f for f in m.groups() if f)
        return found - EXEMPT

    def listed_subcommands(self, path):
        """Names in a 'commands' or 'Subcommands:' section of the help."""
        _, text = self.get(path)
        names = []
        in_list = False
        for line in text.splitlines():
            if re.match(r"^\S", line):
                in_list = bool(re.match(r"^(sub)?commands\b", line, re.I))
                continue
            m = re.match(r"^  ([a-z][a-z0-9-]*)\s", line)
            if in_list and m:
                names.append(m.group(1))
        return names


def discover(helper, readme_paths):
    """All command paths, and the leaves (the ones that need a synopsis entry)."""
    commands, children, seen = set(), {}, set()
    todo = [""] + sorted(readme_paths)
    while todo:
        path = todo.pop()
        if path in commands or path in seen:
            continue
        seen.add(path)
        _, text = helper.get(path)
        if path and not helper.is_command(path):
            # Not a command itself (e.g. `bench` without a subcommand prints a usage line and
            # exits 2), but its text may name the commands below it.
            todo += [m.group(1).strip() for m in MENTION_RE.finditer(text)
                     if m.group(1).strip().startswith(path + " ")]
            continue
        commands.add(path)
        candidates = [(path + " " + n).strip() for n in helper.listed_subcommands(path)]
        candidates += [m.group(1).strip() for m in MENTION_RE.finditer(text)]
        for cand in candidates:
            words = cand.split()
            for i in range(1, len(words) + 1):  # 'optinav bench gnss --out' -> bench, bench gnss
                todo.append(" ".join(words[:i]))
    for path in commands:
        if path:
            parent = path.rsplit(" ", 1)[0] if " " in path else ""
            children.setdefault(parent, set()).add(path)
    # A command needs an entry unless it is only a group: it has subcommands and no own flags
    # beyond the ones every command has (--log-level).
    common = common_flags(helper, commands - {""})
    needs_entry = {p for p in commands
                   if p and (p not in children or helper.flags(p) - common)}
    return commands - {""}, needs_entry


def common_flags(helper, paths):
    """The flags every command that takes options has (e.g. --log-level)."""
    sets = [helper.flags(p) for p in paths if helper.takes_options(p)]
    return set.intersection(*sets) if sets else set()


NOTE_SCOPE_RE = re.compile(r"^([^(:]*)\(([^)]*)\):")


def parse_synopsis(readme_text):
    """(entries {path: text}, notes [(scope or None, flags)], problems) from the README's
    '## Commands' block. A note `Label (cmd, cmd and cmd): flags ...` applies to the commands in
    the parentheses; any other note applies to every command that takes options."""
    sec = re.search(r"^## Commands\s*$(.*?)(?=^## |\Z)", readme_text, re.M | re.S)
    if not sec:
        return {}, [], ["README: no '## Commands' section"]
    block = re.search(r"^```[^\n]*\n(.*?)^```", sec.group(1), re.M | re.S)
    if not block:
        return {}, [], ["README: no ``` synopsis block under '## Commands'"]
    entries, notes, current, note = {}, [], None, None
    for line in block.group(1).splitlines():
        if not line.strip():
            current = note = None
            continue
        m = re.match(r"^optinav((?: [a-z][a-z0-9-]*)*)(.*)$", line)
        if m:
            current, note = m.group(1).strip(), None
            entries[current] = entries.get(current, "") + " " + m.group(2)
        elif line[0].isspace() and current is not None:
            entries[current] += " " + line
        elif line[0].isspace() and note is not None:
            note[1].update(set(TEXT_FLAG_RE.findall(line)) - EXEMPT)
        else:
            current = None
            scope = NOTE_SCOPE_RE.match(line)
            if scope:
                scope = {c.strip() for c in re.split(r",| and ", scope.group(2)) if c.strip()}
            note = (scope, set(TEXT_FLAG_RE.findall(line)) - EXEMPT)
            notes.append(note)
    return entries, notes, []


def check(helper, readme_text):
    entries, notes, problems = parse_synopsis(readme_text)
    if problems:
        return problems
    commands, needs_entry = discover(helper, set(entries))
    for path in sorted(needs_entry - set(entries)):
        problems.append(f"optinav {path}: no synopsis entry in README (--help lists: "
                        f"{' '.join(sorted(helper.flags(path))) or 'no flags'})")
    for path in sorted(set(entries) - commands):
        problems.append(f"optinav {path}: README has a synopsis entry, but "
                        f"`optinav {path} --help` does not know this command")
    for scope, _ in notes:
        for path in sorted((scope or set()) - commands):
            problems.append(f"optinav {path}: a note in the synopsis is for this command, but "
                            f"`optinav {path} --help` does not know it")
    for path in sorted(commands):
        known = helper.flags(path)
        applying = set()
        for scope, flags in notes:
            if (scope is None and helper.takes_options(path)) or (scope and path in scope):
                applying |= flags
        for flag in sorted(applying - known):
            problems.append(f"optinav {path}: a note in the synopsis names {flag}, "
                            f"which --help does not list")
        if path not in entries:
            continue
        named = set(TEXT_FLAG_RE.findall(entries[path])) - EXEMPT
        for flag in sorted(known - named - applying):
            problems.append(f"optinav {path}: --help lists {flag}, the README synopsis does not")
        for flag in sorted(named - known):
            problems.append(f"optinav {path}: the README synopsis names {flag}, "
                            f"which --help does not list")
    return problems


def synthesize(helper, paths, drop_note=False, drop_flag=None, extra_flag=None,
               drop_entry=None, extra_entry=None, scoped_note=None):
    """A synopsis block made from the help texts, with at most one planted mistake per kind."""
    common = common_flags(helper, paths)
    lines = []
    for path in sorted(paths):
        if path == drop_entry:
            continue
        flags = sorted(helper.flags(path) - common)
        if drop_flag and drop_flag[0] == path:
            flags.remove(drop_flag[1])
        if extra_flag and extra_flag[0] == path:
            flags.append(extra_flag[1])
        lines.append(f"optinav {path} [{' '.join(flags)}]".replace(" []", ""))
    if extra_entry:
        lines.append(f"optinav {extra_entry} --out DIR")
    if scoped_note:
        lines.append(f"Shared flags ({', '.join(scoped_note[0])}): {scoped_note[1]}")
        lines.append(f"            {scoped_note[2]}")
    if not drop_note:
        lines.append("Every command also takes " + " ".join(sorted(common)) + ".")
    return "# x\n\n## Commands\n\n```\n" + "\n".join(lines) + "\n```\n\n## Next\n"


def self_test(helper, readme_text=""):
    entries, _, _ = parse_synopsis(readme_text) if readme_text else ({}, set(), [])
    _, needs_entry = discover(helper, set(entries))
    paths = sorted(needs_entry)
    failures, cases = [], []

    def expect(name, text, predicate):
        cases.append(name)
        got = check(helper, text)
        if not predicate(got):
            failures.append(f"self-test '{name}': unexpected result: {got}")

    expect("clean synopsis", synthesize(helper, paths), lambda got: got == [])
    with_flags = [p for p in paths if helper.flags(p)]
    common = common_flags(helper, paths)
    for path in with_flags:
        own = sorted(helper.flags(path) - common)
        if not own:
            continue
        flag = own[len(own) // 2]
        expect(f"drop {flag} from {path}", synthesize(helper, paths, drop_flag=(path, flag)),
               lambda got, p=path, f=flag:
               got == [f"optinav {p}: --help lists {f}, the README synopsis does not"])
        expect(f"add --no-such-flag to {path}",
               synthesize(helper, paths, extra_flag=(path, "--no-such-flag")),
               lambda got, p=path: got == [f"optinav {p}: the README synopsis names "
                                           f"--no-such-flag, which --help does not list"])
    if common:
        expect("drop the note", synthesize(helper, paths, drop_note=True),
               lambda got: len(got) == len(common) * sum(helper.takes_options(p) for p in paths)
               and all("the README synopsis does not" in g for g in got))
    expect(f"drop the entry of {paths[0]}", synthesize(helper, paths, drop_entry=paths[0]),
           lambda got: len(got) == 1 and got[0].startswith(f"optinav {paths[0]}: no synopsis"))
    expect("entry for a command that does not exist",
           synthesize(helper, paths, extra_entry="no-such-command"),
           lambda got: got == ["optinav no-such-command: README has a synopsis entry, but "
                               "`optinav no-such-command --help` does not know this command"])
    # A scoped note: its flags count for the commands it names only, over continuation lines.
    a, b = with_flags[0], with_flags[-1]
    fa = sorted(helper.flags(a) - common)[0]
    fb = sorted(helper.flags(b) - common)[0]
    both = {fa, fb}
    expect(f"scoped note ({a}, {b}) naming {fa} and {fb}",
           synthesize(helper, paths, scoped_note=([a, b, "no-such-command"], fa, fb)),
           lambda got: sorted(got) == sorted(
               [f"optinav no-such-command: a note in the synopsis is for this command, but "
                f"`optinav no-such-command --help` does not know it"]
               + [f"optinav {p}: a note in the synopsis names {f}, which --help does not list"
                  for p in (a, b) for f in sorted(both - helper.flags(p))]))
    if len(paths) < 5:
        failures.append(f"self-test: only {len(paths)} commands discovered: {paths}")
    return failures, len(cases)


def main(argv):
    args = argv[1:]
    only_self_test = "--self-test" in args
    args = [a for a in args if a != "--self-test"]
    if len(args) != (1 if only_self_test else 2):
        print(__doc__.split("\n\n")[1], file=sys.stderr)
        return 2
    helper = Help(args[0])
    readme_text = ""
    if not only_self_test:
        with open(args[1], encoding="utf-8") as f:
            readme_text = f.read()
    failures, cases = self_test(helper, readme_text)
    for line in failures:
        print(line)
    if failures or only_self_test:
        print(f"self-test: {len(failures)} of {cases} cases FAILED" if failures
              else f"self-test: ok ({cases} cases)")
        return 1 if failures else 0
    problems = check(helper, readme_text)
    for line in problems:
        print(f"{args[1]}: {line}")
    entries, _, _ = parse_synopsis(readme_text)
    if problems:
        print(f"README synopsis: {len(problems)} problem(s); `optinav <command> --help` is the "
              f"reference")
        return 1
    print(f"README synopsis: ok ({len(entries)} entries agree with --help; "
          f"self-test ok, {cases} cases)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
