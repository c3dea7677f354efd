"""`python -m ph_explorer.cli` runs the ph-explorer command line."""

from ph_explorer.cli import main

if __name__ == "__main__":
    main()
