"""``python -m rodcont ...`` does what the ``rodcont`` console script does."""

if __name__ == "__main__":
    try:
        from rodcont._entry import main
    except KeyboardInterrupt:  # an interrupt before _entry's handler (rodcont/__init__ installs it first)
        import sys
        sys.stderr.write("rodcont: interrupted\n")
        sys.exit(130)
    main()
