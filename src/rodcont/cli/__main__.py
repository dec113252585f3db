"""``python -m rodcont.cli ...``, as before the CLI became a package."""

from rodcont._entry import main

if __name__ == "__main__":
    main()
