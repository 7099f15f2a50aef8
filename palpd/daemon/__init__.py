"""The palpd service: supervisor (bus, commands, recorder, sd_notify), scan worker, sessions."""
