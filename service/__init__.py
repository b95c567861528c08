"""The LumenLink service: FastAPI app, wire schemas, tree diff and apply, SQLite storage, simulation routes."""
