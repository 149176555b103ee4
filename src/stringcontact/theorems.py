"""PLACEHOLDER: being written by its issue's helper; replaced before landing."""


def add_arguments(parser):
    parser.add_argument("args", nargs="*")


def command(args) -> int:
    raise SystemExit("not yet implemented")


def write_pictures(result, folder):
    pass
