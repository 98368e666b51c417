// An independent VDA 5050 master control for the adapter's tests: npm's vda-5050-lib
// (MasterController, VDA 5050 2.0.0), which validates every message it receives against
// its own compiled 2.0 schemas and drops one that fails.
//
// Commands come as JSON lines on stdin, each with an "id"; what happens goes out as JSON
// lines on stdout ({"event": ...}, with the command's "id" where it answers one):
//   {"cmd": "start", "brokerUrl", "username", "password", "interfaceName", "manufacturer", "serialNumber"}
//   {"cmd": "order", "order": {...headerless order}}       -> orderProcessed, nodeTraversed, actionState
//   {"cmd": "instant", "actions": [...]}                     -> instantActionState, instantActionError
//   {"cmd": "raw", "topic": "order", "payload": "<text>"}    a message the library would refuse to send
//   {"cmd": "validate", "topic": "state", "object": {...}}   -> validated, with the 2.0 validator's errors
//   {"cmd": "stop"}
// Every message received from the vehicle is echoed ({"event": "message", "topic", "object"});
// one the library drops as invalid is reported ({"event": "dropped", "text"}).
'use strict';

const readline = require('readline');
const mqtt = require('mqtt');
const { MasterController, Topic } = require('vda-5050-lib');
const validators = require('vda-5050-lib/common/vda-5050-validators-2.0');

const VALIDATORS = {
    order: validators.validateOrder,
    instantActions: validators.validateInstantActions,
    state: validators.validateState,
    connection: validators.validateConnection,
    visualization: validators.validateVisualization,
    factsheet: validators.validateFactsheet,
};

let controller;
let rawClient;
let agvId;
let options;

function emit(event) {
    process.stdout.write(JSON.stringify(event) + '\n');
}

// The library reports a dropped inbound message on console.error.
console.error = (...args) => emit({ event: 'dropped', text: args.map(String).join(' ') });

function topicOf(name) {
    return `${options.interfaceName}/v2/${options.manufacturer}/${options.serialNumber}/${name}`;
}

async function start(command) {
    options = command;
    agvId = { manufacturer: command.manufacturer, serialNumber: command.serialNumber };
    const transport = {
        brokerUrl: command.brokerUrl,
        username: command.username,
        password: command.password,
        heartbeat: 5,
    };
    controller = new MasterController(
        { interfaceName: command.interfaceName, transport, vdaVersion: '2.0.0' },
        { targetAgvs: agvId },
    );
    await controller.start();
    for (const topic of [Topic.State, Topic.Connection, Topic.Factsheet, Topic.Visualization]) {
        await controller.subscribe(topic, agvId, object => emit({ event: 'message', topic, object }));
    }
    // a second connection, for what the library itself would never send
    rawClient = mqtt.connect(command.brokerUrl, {
        username: command.rawUsername,
        password: command.rawPassword,
        clientId: command.rawUsername,
    });
    await new Promise((resolve, reject) => {
        rawClient.once('connect', resolve);
        rawClient.once('error', reject);
    });
}

function orderHandler(orderId) {
    return {
        onOrderProcessed: (error, byCancelation, active, context) => emit({
            event: 'orderProcessed', orderId, error: error || null, byCancelation, active,
            orderUpdateId: context.order.orderUpdateId,
        }),
        onNodeTraversed: node => emit({ event: 'nodeTraversed', orderId, nodeId: node.nodeId, sequenceId: node.sequenceId }),
        onActionStateChanged: (actionState, error) => emit({
            event: 'actionState', orderId, actionState, error: error || null,
        }),
    };
}

const instantHandler = {
    onActionStateChanged: (actionState, error) => emit({ event: 'instantActionState', actionState, error: error || null }),
    onActionError: (error, action) => emit({ event: 'instantActionError', actionId: action.actionId, error }),
};

async function handle(command) {
    switch (command.cmd) {
        case 'start':
            await start(command);
            return {};
        case 'order':
            await controller.assignOrder(agvId, command.order, orderHandler(command.order.orderId));
            return {};
        case 'instant':
            await controller.initiateInstantActions(agvId, { instantActions: command.actions }, instantHandler);
            return {};
        case 'raw':
            await new Promise((resolve, reject) => rawClient.publish(
                topicOf(command.topic), command.payload, { qos: 0 }, error => (error ? reject(error) : resolve())));
            return {};
        case 'validate': {
            const validate = VALIDATORS[command.topic];
            const valid = validate(command.object);
            return { valid, errors: valid ? [] : validate.errors };
        }
        case 'stop':
            if (rawClient) {
                rawClient.end(true);
            }
            if (controller) {
                await controller.stop();
            }
            return {};
        default:
            throw new Error(`unknown command ${command.cmd}`);
    }
}

const lines = readline.createInterface({ input: process.stdin });
lines.on('line', async line => {
    let command;
    try {
        command = JSON.parse(line);
        const answer = await handle(command);
        emit({ event: 'done', id: command.id, ...answer });
        if (command.cmd === 'stop') {
            process.exit(0);
        }
    } catch (error) {
        emit({ event: 'failed', id: command && command.id, error: String(error && error.message || error) });
    }
});
lines.on('close', () => process.exit(0));
emit({ event: 'ready' });
