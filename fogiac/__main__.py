from fogiac.cli import main

main()
