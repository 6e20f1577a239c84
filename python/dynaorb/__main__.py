from dynaorb.cli import main

raise SystemExit(main())
