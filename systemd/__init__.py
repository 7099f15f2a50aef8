"""The systemd unit and udev rule template, shipped as palpd.share.systemd (`palpd files` prints them)."""
