"""The MRBA twin: mobile base and passive arm, harness, fall rule, follow-me controllers."""
