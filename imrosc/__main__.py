"""``python -m imrosc`` is the ``imrosc`` command."""

from imrosc.cli import main

if __name__ == "__main__":
    main()
