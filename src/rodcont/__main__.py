"""``python -m rodcont ...`` does what the ``rodcont`` console script does."""

from rodcont._entry import main

if __name__ == "__main__":
    main()
