"""The command line: `stringcontact run|list|show` and the subcommands of the layers below.

The top layer: it may import any package. Exit codes and signals: docs/explanation/reliability.md.
"""
