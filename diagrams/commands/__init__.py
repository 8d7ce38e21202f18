"""The CLI's commands: flags -> a typed request -> one library call -> text."""
