"""The ZeroMQ bus: event topics (PUB) and commands (ROUTER), with pydantic message models."""
