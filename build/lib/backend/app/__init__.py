"""The HTTP service: FastAPI app factory, routers, storage, and the SQLite metadata store."""
