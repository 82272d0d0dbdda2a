"""The generic, declarative binary codec: field types and the engine behind them. No I/O."""
