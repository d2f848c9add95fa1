from softflow.cli import main

main()
