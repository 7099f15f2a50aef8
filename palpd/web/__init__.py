"""The live web view the daemon serves at `daemon.http`: one page, updated by server-sent events."""
