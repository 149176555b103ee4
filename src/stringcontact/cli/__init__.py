"""The command line: `stringcontact run|list|show|models|plot|study|check`, its parser and the process around it.

The top layer: it may import any package. Exit codes and signals: docs/explanation/reliability.md.
"""
