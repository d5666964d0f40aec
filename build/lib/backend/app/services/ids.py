"""Identifiers: short, random, URL- and file-name-safe."""
import secrets


def new_id() -> str:
    return secrets.token_hex(6)
