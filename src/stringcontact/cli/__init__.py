"""The command line: `stringcontact run|list|show|plot|study|check|models`, its parser and the process around it.

The top layer: it may import any package. Exit codes and signals: docs/explanation/reliability.md.
"""
