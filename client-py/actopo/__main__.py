"""`python -m actopo ...` runs the CLI."""

from actopo._cli import main

raise SystemExit(main())
