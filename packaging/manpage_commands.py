#!/usr/bin/python3
"""Writes help2man's include file for maglead(1) from the commands' own --help.

usage: manpage_commands.py MAGLEAD OUT.h2m

Runs `MAGLEAD --help`, then `MAGLEAD COMMAND --help` for every command (and every subcommand of
a command, as `bench modbus`), and writes:
  [NAME]          "maglead - " and the first sentence of `maglead --help`;
  [=DESCRIPTION]  the description of `maglead --help`, without its pointer to this page;
  [COMMANDS]      every command: its one-line help, usage, positionals and options (CLI11's
                  layout parsed into roff: an entry per option, its continuation lines kept);
  [SEE ALSO]      where the rest of the documentation is installed.
help2man itself makes SYNOPSIS and OPTIONS (the global options and the list of commands)
from `maglead --help`. Fails when the help cannot be read or lists no command.
"""
import re
import subprocess
import sys

MAGLEAD, OUT = sys.argv[1], sys.argv[2]
# The sentence of `maglead --help` that points to this page: left out of the page itself.
POINTER = re.compile(r"\s*See man (maglead|-l \S+) for every command\.")
SEE_ALSO = r"""[SEE ALSO]
The README and the Modbus register map are installed in
.IR share/doc/maglead
under the installation prefix
.RI ( /usr/share/doc/maglead
for the Debian package); the configuration files in
.I /etc/maglead
(package) or
.IR share/maglead .
"""


def help_of(*path):
    r = subprocess.run([MAGLEAD, *path, "--help"], capture_output=True, text=True, timeout=30)
    if r.returncode != 0 or "Usage:" not in r.stdout:
        sys.exit(f"manpage_commands: maglead {' '.join(path)} --help failed ({r.returncode}): {r.stderr}")
    return r.stdout


def roff(text):
    """Plain text as roff: backslashes and minus signs escaped, other than ASCII as groff's
    \\[uXXXX], no control character first."""
    text = text.replace("\\", "\\e").replace("-", "\\-")
    text = "".join(c if ord(c) < 128 else f"\\[u{ord(c):04X}]" for c in text)  # any locale
    return "\\&" + text if text[:1] in (".", "'") else text


def parse(text):
    """CLI11's help: (description lines, usage, blocks); a block is (heading, note lines,
    entries), an entry (spec, description lines)."""
    lines = text.rstrip("\n").split("\n")
    at = next(i for i, line in enumerate(lines) if line.startswith("Usage:"))
    description = [line.strip() for line in lines[:at] if line.strip()]
    usage = lines[at][len("Usage:"):].strip()
    blocks, block, entry = [], None, None
    for line in lines[at + 1:]:
        stripped = line.strip()
        indent = len(line) - len(line.lstrip(" "))
        if not stripped:
            continue
        group = re.fullmatch(r"\[Option Group: (.*)\]", stripped)
        if group or (indent == 0 and stripped.endswith(":")):
            block = (group.group(1) if group else stripped[:-1], [], [])
            blocks.append(block)
            entry = None
        elif stripped in ("Options:", "Positionals:"):
            continue  # the options of a group: under the group's heading
        elif indent >= 16 and entry is not None:
            entry[1].append(stripped)  # a description on its own line, or its continuation
        elif re.fullmatch(r"\[.*\]", stripped) or (block[2] == [] and not stripped.startswith("-")
                                                   and block[0] not in ("Positionals", "Subcommands")):
            block[1].append(stripped.strip("[]"))  # a group's description or constraint
        else:
            m = re.fullmatch(r"(\S.*?)(?:\s{2,}(\S.*))?", stripped)
            entry = (m.group(1), [m.group(2)] if m.group(2) else [])
            block[2].append(entry)
    return description, usage, blocks


def spec_roff(spec):
    """`--port INT:INT in [1 - 65535]=1502`: the names bold, the value's form as it is."""
    names, _, rest = spec.partition(" ")
    bold = ",".join(f"\\fB{roff(n)}\\fR" for n in names.split(","))
    return bold + (" " + roff(rest) if rest else "")


def command_roff(path, out, commands):
    description, usage, blocks = parse(help_of(*path))
    out.append(f'.SS "{roff("maglead " + " ".join(path))}"')
    out.extend(roff(d) for d in description)
    out.append(".PP")
    name = "maglead " + " ".join(path)
    rest = usage[len(name):].strip() if usage.startswith(name) else usage
    out.append(f"Usage: \\fB{roff(name)}\\fR {roff(rest)}".rstrip())
    subcommands = []
    for heading, notes, entries in blocks:
        entries = [e for e in entries if e[0] != "-h,--help"]
        if not entries:
            continue
        if heading == "Subcommands":
            subcommands = [e[0] for e in entries]
        out.append(".PP")
        out.append(f"\\fI{roff(heading)}:\\fR" + (" " + roff("; ".join(notes)) if notes else ""))
        for spec, text in entries:
            out.append(".TP")
            out.append(spec_roff(spec) if heading != "Subcommands" else f"\\fB{roff(spec)}\\fR")
            for k, t in enumerate(text):
                if k:
                    out.append(".br")
                out.append(roff(t))
    commands.append(" ".join(path))
    for sub in subcommands:
        command_roff(path + [sub], out, commands)


def main():
    description, _, blocks = parse(help_of())
    top = [e[0] for heading, _, entries in blocks if heading == "Subcommands" for e in entries]
    if not top:
        sys.exit("manpage_commands: `maglead --help` lists no command")
    text = POINTER.sub("", " ".join(description)).strip()
    # NAME: the description's first sentence after "maglead: ".
    name = re.match(r"(?:maglead: )?(.*?)\.(?:\s|$)", text)
    if not name:
        sys.exit(f"manpage_commands: no first sentence in `maglead --help`: {text}")
    out = ["[NAME]", f"maglead \\- {roff(name.group(1))}", "", "[=DESCRIPTION]", roff(text), "",
           "[COMMANDS]",
           roff("Each command's one-line help, usage and options, as `maglead COMMAND --help` "
                "prints them. Every command also takes -h, --help and the options above.")]
    commands = []
    for name in top:
        command_roff([name], out, commands)
    out += ["", SEE_ALSO]
    with open(OUT, "w", encoding="utf-8") as f:
        f.write("\n".join(out) + "\n")
    print(f"manpage_commands: {len(commands)} commands into {OUT}")


if __name__ == "__main__":
    main()
