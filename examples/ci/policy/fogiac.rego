# A conftest policy for fogiac's plan as Terraform plan JSON (`fogiac plan --format terraform-json`):
#   conftest test tfplan.json --policy examples/ci/policy
# It reads the same document checkov does; add your organisation's rules beside these.
package main

import rego.v1

resources := input.planned_values.root_module.resources

# Every instance requires IMDSv2 tokens.
deny contains msg if {
	some r in resources
	r.type == "aws_instance"
	some m in r.values.metadata_options
	m.http_tokens != "required"
	msg := sprintf("%s: IMDSv2 is not required (metadata_options.http_tokens = %v)", [r.address, m.http_tokens])
}

# Every root volume is encrypted.
deny contains msg if {
	some r in resources
	r.type == "aws_instance"
	some d in r.values.root_block_device
	not d.encrypted
	msg := sprintf("%s: the root volume is not encrypted", [r.address])
}

# The hosts reach the internet only on the TCP ports agreed here (fogiac's default: 80 and 443;
# network.egress_tcp in the manifest adds more, and then this list must say so too).
allowed_egress_tcp := {80, 443}

deny contains msg if {
	some r in resources
	r.type == "aws_vpc_security_group_egress_rule"
	r.values.cidr_ipv4 == "0.0.0.0/0"
	not egress_allowed(r.values)
	msg := sprintf("%s: egress to the internet on %v %v, not in allowed_egress_tcp", [
		r.address, r.values.ip_protocol, object.get(r.values, "from_port", "(all ports)"),
	])
}

egress_allowed(v) if {
	v.ip_protocol == "tcp"
	v.from_port == v.to_port
	v.from_port in allowed_egress_tcp
}

# No ingress from the whole internet (fogiac refuses it too; this keeps hand edits honest).
deny contains msg if {
	some r in resources
	r.type == "aws_vpc_security_group_ingress_rule"
	r.values.cidr_ipv4 == "0.0.0.0/0"
	msg := sprintf("%s: ingress from 0.0.0.0/0", [r.address])
}
