"""The command-line door: :mod:`gearwatch.cli.main` builds the parser from the sub-commands in
:mod:`gearwatch.cli.commands`; :mod:`gearwatch.cli.shared` holds what several commands share
(option helpers, printing, serving). A command parses, calls one use-case and prints; no command
imports another."""
