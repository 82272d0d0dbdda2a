"""JAUS protocol knowledge: addresses, the AS5669A transport, the message catalogue. No I/O."""
