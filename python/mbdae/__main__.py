"""``python3 -m mbdae sweep STUDY.yaml ...``: the Python commands of the mbdae program
(``mbdae sweep`` runs the same; docs/sweeps.md)."""

import sys


def main(argv=None):
    argv = sys.argv[1:] if argv is None else list(argv)
    if not argv or argv[0] != "sweep":
        sys.stderr.write("usage: python3 -m mbdae sweep STUDY.yaml [options] "
                         "(python3 -m mbdae sweep --help)\n")
        return 2
    from .sweep import main as sweep_main

    return sweep_main(argv[1:])


if __name__ == "__main__":
    sys.exit(main())
