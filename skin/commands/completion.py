"""``skin completion bash``: a completion script for bash (and zsh through bashcompinit).

Load it in a shell with ``source <(skin completion bash)``, or keep it with
``skin completion bash > ~/.local/share/bash-completion/completions/skin``. It completes the
commands, their subcommands, their options and the choices of options that have them, and
falls back to file names. In zsh, run ``autoload -U bashcompinit && bashcompinit`` first.
"""

from __future__ import annotations

import argparse
import shlex


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register ``skin completion``."""
    comp = sub.add_parser("completion", help="print a shell completion script",
                          description=__doc__)
    comp.add_argument("shell", choices=("bash",), help="the shell (bash; zsh via bashcompinit)")
    comp.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    """Print the script."""
    from skin.cli import build_parser

    print(bash_script(build_parser()))
    return 0


def _walk(parser: argparse.ArgumentParser, path: str, table: dict[str, dict[str, str]]) -> None:
    """Fill ``table`` (sub, opts, choices) from ``parser``, the command path ``path``."""
    words: list[str] = []
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            table["sub"][path] = " ".join(action.choices)
            for name, child in action.choices.items():
                _walk(child, f"{path} {name}", table)
        elif action.option_strings:
            words += [o for o in action.option_strings if o.startswith("--")] or \
                action.option_strings
            if action.choices is not None:
                for option in action.option_strings:
                    table["choices"][f"{path} {option}"] = " ".join(map(str, action.choices))
        elif action.choices is not None:  # a positional with choices
            table["sub"].setdefault(path, " ".join(map(str, action.choices)))
    table["opts"][path] = " ".join(words)


def bash_script(parser: argparse.ArgumentParser) -> str:
    """Return the bash completion script of ``parser`` (the ``skin`` command)."""
    table: dict[str, dict[str, str]] = {"sub": {}, "opts": {}, "choices": {}}
    _walk(parser, "skin", table)
    lines = ["# bash completion of skin (thermoskin): source <(skin completion bash)"]
    for name, values in table.items():
        lines.append(f"declare -gA _skin_{name}=(")
        lines += [f"  [{shlex.quote(key)}]={shlex.quote(value)}"
                  for key, value in sorted(values.items())]
        lines.append(")")
    lines.append('''_skin() {
  local cur=${COMP_WORDS[COMP_CWORD]} prev=${COMP_WORDS[COMP_CWORD-1]} path=skin w i
  for ((i = 1; i < COMP_CWORD; i++)); do
    w=${COMP_WORDS[i]}
    case " ${_skin_sub[$path]} " in *" $w "*) path="$path $w" ;; esac
  done
  COMPREPLY=()
  if [[ -n ${_skin_choices["$path $prev"]} ]]; then
    COMPREPLY=($(compgen -W "${_skin_choices["$path $prev"]}" -- "$cur"))
  elif [[ $cur == -* ]]; then
    COMPREPLY=($(compgen -W "${_skin_opts[$path]}" -- "$cur"))
  elif [[ -n ${_skin_sub[$path]} ]]; then
    COMPREPLY=($(compgen -W "${_skin_sub[$path]}" -- "$cur"))
  fi
}
complete -o default -F _skin skin''')
    return "\n".join(lines)
