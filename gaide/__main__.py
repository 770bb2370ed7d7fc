from gaide.cli import main

raise SystemExit(main())
