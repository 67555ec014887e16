from laminid_cli.cli import main

main()
