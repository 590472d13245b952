"""`fiberfem web`: a bridge that joins the DDS domain like any client and serves a page that
shows and steers the runs on it (docs/web.md). Run as `python -m fiberfem_client.web`."""
