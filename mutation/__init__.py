"""Mutation testing of the safety-relevant code (`make mutate`, docs/verification.md).

Small source-level mutations (relational operators, constants at limits and thresholds,
removed statements and conditions, swapped signs and logic) of the firmware application,
of the templates that emit generated/ and of the generator's model-to-number path. Each
mutant is built (and generated/ regenerated from a mutated template or model module) in a
worker's copy of the tree and the relevant behavioural tests run against it: a mutant the
tests do not kill shows a bug they would miss.
"""
