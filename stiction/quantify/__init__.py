"""How large the stiction is: the He & Wang (2014) reading of a limit cycle
(:mod:`.hewang`) and the choice among the sizing routes (:mod:`.route`)."""
